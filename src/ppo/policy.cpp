#include "ppo/policy.hpp"

#include <stdexcept>

namespace hns::ppo {

namespace {
constexpr uint64_t kPlayStream = 0xA5A5'0003'0000'0000ULL;
}

Policy::Policy(const Trainer& trainer, uint64_t seed) : trainer_(&trainer), seed_(seed) {}

Policy::Policy(std::unique_ptr<Trainer> owned, uint64_t seed)
    : owned_(std::move(owned)), trainer_(owned_.get()), seed_(seed) {}

Policy::~Policy() = default;

std::unique_ptr<Policy> Policy::from_checkpoint(const std::string& path, uint64_t seed) {
  TrainConfig cfg = Trainer::checkpoint_config(path);
  cfg.envs = 1;  // the trainer only holds the networks here
  cfg.threads = 1;
  cfg.minibatches = 1;
  cfg.minibatch_chunks = 0;  // the run's may not fit one env
  // Acting only: a bf16 run acts in bf16 where this CPU has it, else in fp32 (its float master weights are
  // the same; the actions may differ in rare near-ties). Training a run on (--resume) never changes its
  // precision.
  if (cfg.precision == "bf16") cfg.precision = "auto";
  auto trainer = std::make_unique<Trainer>(cfg);
  trainer->load(path, Trainer::LoadMode::kPolicy);
  return std::unique_ptr<Policy>(new Policy(std::move(trainer), seed));
}

const nn::ObsShape& Policy::obs_shape() const {
  return trainer_->net().config().obs;
}

int Policy::state_width() const {
  return trainer_->net().state_width();
}

void Policy::resize(int envs) {
  const int G = envs * obs_shape().max_agents;
  if (rows_ == G) return;
  const int heads = trainer_->net().heads().num_heads(), sw = state_width();
  rows_ = G;
  obs_.allocate(obs_shape(), size_t(G));
  state_p_.resize(size_t(G) * sw);
  state_v_.resize(size_t(G) * sw);
  uniforms_.resize(size_t(G) * heads);
  actions_.assign(size_t(G) * heads, 0);
  // The sampling streams stay: env e's stream is (seed, e, episode) whatever batch size asks next.
  if (streams_.size() < size_t(envs)) {
    streams_.resize(size_t(envs));
    stream_episode_.resize(size_t(envs), -1);
  }
}

void Policy::act(const batch::BatchSim& sim, std::span<physics::AgentAction> actions) {
  const nn::ObsShape& shape = obs_shape();
  const batch::Layout& L = sim.layout();
  if (L.max_agents != shape.max_agents || L.max_boxes != shape.max_boxes || L.max_ramps != shape.max_ramps ||
      L.max_sites != shape.max_sites || (L.max_sites > 0 && L.site_features != shape.site_features)) {
    throw std::invalid_argument("the policy was trained on scene '" + trainer_->config().scene +
                                "'; this batch has other entity maxima");
  }
  resize(sim.num_envs());
  act(StepObsView::of(sim.state()), sim.num_envs(), state_p_.data(), state_v_.data(), actions);
}

void Policy::act(const StepObsView& obs, int envs, float* policy_state, float* value_state,
                 std::span<physics::AgentAction> actions) {
  const nn::ActorCritic& net = trainer_->net();
  const nn::ObsShape& shape = obs_shape();
  const int A = shape.max_agents, G = envs * A;
  const int heads = net.heads().num_heads();
  if (actions.size() != size_t(G))
    throw std::invalid_argument("Policy::act: actions must hold envs x max_agents");
  resize(envs);
  const nn::ObsNormView norm = trainer_->obs_normalizer().view();
  obs_.copy_step(obs, size_t(G), 0, &norm);
  for (int e = 0; e < envs; ++e) {
    if (stream_episode_[e] != obs.episode[e]) {
      streams_[e] = physics::Rng(seed_ ^ kPlayStream, uint64_t(e), uint64_t(obs.episode[e]));
      stream_episode_[e] = obs.episode[e];
    }
    for (int a = 0; a < A; ++a) {
      obs_.reset[size_t(e) * A + a] = obs.step_count[e] == 0 ? 1.0f : 0.0f;
      for (int h = 0; h < heads; ++h)
        uniforms_[(size_t(e) * A + a) * heads + h] = float(streams_[e].next_u64() >> 40) * 0x1.0p-24f;
    }
  }
  nn::ActorCritic::ActOutputs out;
  out.actions = actions_.data();
  net.act(nn::ObsNormView::identity(), obs_.batch(), G, policy_state, value_state, uniforms_.data(), out);
  for (int g = 0; g < G; ++g) {
    const int32_t* a = actions_.data() + size_t(g) * heads;
    actions[g] = {uint8_t(a[0]), uint8_t(a[1]), uint8_t(a[2]), uint8_t(a[3]), uint8_t(a[4])};
  }
}

}  // namespace hns::ppo
