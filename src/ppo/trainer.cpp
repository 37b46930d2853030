#include "ppo/trainer.hpp"

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/enumerable_thread_specific.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "nn/bf16_gemm.hpp"
#include "physics/rng.hpp"
#include "ppo/batch_obs.hpp"
#include "ppo/ppo_loss.hpp"
#include "ppo/ppo_math.hpp"

namespace hns::ppo {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Streams of the counter-derived random numbers (physics::Rng(seed ^ stream, iteration, step)).
constexpr uint64_t kActionStream = 0xA5A5'0001'0000'0000ULL;
constexpr uint64_t kShuffleStream = 0xA5A5'0002'0000'0000ULL;

constexpr int kNumStats = kNumPpoStats;
// Per update block: episodes, then the sums of hider and seeker returns, of the HNS_EPISODE_STATS and of the
// intrinsic returns.
#define HNS_COUNT_EPISODE_STAT(name, doc) +1
constexpr int kBlockEpisodeValues = 3 HNS_EPISODE_STATS(HNS_COUNT_EPISODE_STAT) + 1;
#undef HNS_COUNT_EPISODE_STAT

float uniform_float(physics::Rng& rng) {
  return float(rng.next_u64() >> 40) * 0x1.0p-24f;
}

}  // namespace

void ScalarNormalizer::update(double batch_mean, double batch_sq) {
  biased_mean = beta * biased_mean + (1 - beta) * batch_mean;
  biased_sq = beta * biased_sq + (1 - beta) * batch_sq;
  debias = beta * debias + (1 - beta);
}

double ScalarNormalizer::std() const {
  if (debias <= 0) return 1.0;
  const double m = mean();
  return std::sqrt(std::max(biased_sq / debias - m * m, nn::kObsNormVarFloor));
}

struct Trainer::Buffers {
  // Rollout, step-major: row = t * G + g. Observations normalised once, as they are copied from the
  // simulator (the normaliser does not move during an iteration), and read by both networks in the rollout
  // and in every epoch of the update.
  nn::ObsStore obs;
  std::vector<int32_t> actions;      // [T*G, heads]
  nn::FloatBuffer logp;              // [T*G] log-probability of the sampled actions
  nn::FloatBuffer value_norm;        // [T*G] value head (normalised)
  nn::FloatBuffer value;             // [T*G] de-normalised value
  nn::FloatBuffer reward;            // [T*G]
  nn::FloatBuffer adv;               // [T*G] advantages, z-scored
  nn::FloatBuffer ret;               // [T*G] TD(λ) targets
  nn::FloatBuffer ret_norm;          // [T*G] normalised targets
  std::vector<uint8_t> mask;         // [T*G] 1 for a real agent
  std::vector<uint8_t> last;         // [T*G] 1 if the step ended the agent's episode or the window
  nn::FloatBuffer state_p, state_v;  // [T/bptt, G, state width] LSTM states entering each chunk
  // Live rollout state.
  nn::FloatBuffer cur_p, cur_v;                 // [G, state width]
  nn::FloatBuffer uniforms;                     // [G, heads]
  std::vector<batch::AgentAction> env_actions;  // [G]
  // Minibatch, sequence-major: row = k * bptt + j is rollout row mb_index[row] (the observations are read
  // through the index, the targets and states gathered).
  std::vector<int32_t> mb_index;
  std::vector<int32_t> mb_actions;
  nn::FloatBuffer mb_logp, mb_adv, mb_ret;
  std::vector<uint8_t> mb_mask;
  nn::FloatBuffer mb_state_p, mb_state_v;
  // Update blocks (gradient groups): block k holds envs [E k / K, E (k + 1) / K) and their valid chunk ids
  // c * G + g, shuffled per epoch; a minibatch takes an equal share of every block, block by block.
  std::vector<std::vector<int32_t>> block_chunks;  // [K][its valid chunks]
  std::vector<int32_t> mb_chunks;                  // the current minibatch's chunk ids, block by block
  std::vector<int> mb_groups;                      // [K + 1] its sequence ranges per block
  std::vector<double> all_chunk_stats;             // every rank's chunk statistics of the minibatch
  std::vector<int32_t> episode_start;  // [this rank's envs] rollout step at which its current episode started
  std::vector<int> block_of;           // [this rank's envs] the local update block of local env e
  // Observation normaliser sums of the rollout's real agent-steps: per env those of its current episode,
  // added to its block's when the episode ends (dropped if it is discarded for numerical trouble, like every
  // other statistic of such an episode), the open ones at the end of the rollout in env order; the blocks'
  // are merged in block order (across ranks).
  std::vector<nn::ObsNormalizer::Sums> block_obs_sums;    // [this rank's blocks]
  std::vector<nn::ObsNormalizer::Sums> episode_obs_sums;  // [this rank's envs]
  // Per block of this rank: episodes that ended, then the sums of their hider and seeker returns and of the
  // HNS_EPISODE_STATS (kBlockEpisodeValues doubles each).
  std::vector<double> block_episodes;
  tbb::enumerable_thread_specific<PpoLossScratch> loss_scratch;  // per thread
};

// The update's sums over its minibatches: the PPO statistics, the gradient norms and the Adam steps taken.
struct Trainer::UpdateSums {
  double stats[kNumStats] = {};
  double grad_norm = 0;
  int updates = 0;
};

std::string IterationMetrics::to_json() const {
  std::string out;
  out.reserve(2048);
  char buf[96];
  auto add = [&](const char* key, const char* format, auto value) {
    std::snprintf(buf, sizeof buf, format, value);
    out += out.empty() ? "{\"" : ", \"";
    out += key;
    out += "\": ";
    out += buf;
  };
  add("iteration", "%lld", static_cast<long long>(iteration));
  if (!precision.empty()) out += ", \"precision\": \"" + precision + "\"";
  // The bf16 products' kernel (AMX tiles or vdpbf16ps): the two round differently.
  if (precision == "bf16")
    out += ", \"bf16_kernel\": \"" + std::string(nn::bf16::kernel_name(nn::bf16::kernel())) + "\"";
  add("agent_steps", "%lld", static_cast<long long>(agent_steps));
  add("env_steps", "%lld", static_cast<long long>(env_steps));
  add("seconds", "%.4f", seconds);
  add("steps_per_s", "%.1f", steps_per_s);
  add("episodes", "%d", episodes);
  add("hider_reward", "%.6g", hider_reward);
  add("seeker_reward", "%.6g", seeker_reward);
  add("intrinsic_reward", "%.6g", intrinsic_reward);
#define HNS_ADD_EPISODE_MEAN(name, doc) add(#name, "%.6g", name);
  HNS_EPISODE_STATS(HNS_ADD_EPISODE_MEAN)
#undef HNS_ADD_EPISODE_MEAN
  add("policy_loss", "%.6g", policy_loss);
  add("value_loss", "%.6g", value_loss);
  add("entropy", "%.6g", entropy);
  add("approx_kl", "%.6g", approx_kl);
  add("clip_frac", "%.6g", clip_frac);
  add("explained_variance", "%.6g", explained_variance);
  add("grad_norm", "%.6g", grad_norm);
  add("value_mean", "%.6g", value_mean);
  add("value_std", "%.6g", value_std);
  add("time_simulate", "%.4f", t_simulate);
  add("time_observe", "%.4f", t_observe);
  add("time_infer", "%.4f", t_infer);
  add("time_learn", "%.4f", t_learn);
  add("time_targets", "%.4f", t_targets);
  add("time_backward", "%.4f", t_backward);
  add("time_optimizer", "%.4f", t_optimizer);
  add("time_intrinsic", "%.4f", t_intrinsic);
  add("time_other", "%.4f", t_other);
  add("time_comm", "%.4f", t_comm);
  add("unstable_resets", "%lld", static_cast<long long>(unstable_resets));
  out += "}";
  return out;
}

Trainer::Trainer(const TrainConfig& config, Comm* comm) : cfg_(config), buf_(std::make_unique<Buffers>()) {
  cfg_.validate();
  // auto becomes the precision that runs here, so config() and the checkpoint name it (ConfigError for bf16
  // on a CPU without it).
  const nn::Precision precision = cfg_.resolve_precision();
  cfg_.precision = std::string(nn::precision_name(precision));
  if (comm == nullptr) {
    own_comm_ = std::make_unique<SingleProcess>();
    comm = own_comm_.get();
  }
  comm_ = comm;
  blocks_ = cfg_.update_blocks();
  const int R = comm_->size(), r = comm_->rank();
  if (R > blocks_) {
    throw physics::ConfigError(std::to_string(R) + " ranks for " + std::to_string(blocks_) +
                               " update blocks (min(grad_groups, envs), fewer for a small buffer; "
                               "docs/training.md): every rank needs a "
                               "block of envs of its own; use at most " +
                               std::to_string(blocks_) +
                               " ranks or raise grad_groups (and envs; where the buffer is small, lower "
                               "chunk_sequences)");
  }
  block0_ = int(int64_t(blocks_) * r / R);
  block1_ = int(int64_t(blocks_) * (r + 1) / R);
  env0_ = block_env(block0_);
  env1_ = block_env(block1_);
  batch::BatchConfig bc = cfg_.batch_config();
  bc.num_envs = env1_ - env0_;
  bc.first_env = env0_;
  bc.threads = cfg_.threads > 0 ? cfg_.threads : tbb::this_task_arena::max_concurrency();
  bc.seed = cfg_.seed;
  sim_ = std::make_unique<batch::BatchSim>(bc);
  const batch::Layout& L = sim_->layout();

  nn::NetConfig nc = nn::net_preset(cfg_.model);
  nc.obs = obs_shape(L);
  nn::ParallelConfig par;
  par.grad_groups = cfg_.grad_groups;
  // 0 becomes the model's chunk, so config() and the checkpoint name the chunk that ran.
  cfg_.chunk_sequences = cfg_.train_chunk();
  par.train_chunk_sequences = cfg_.chunk_sequences;
  net_ = std::make_unique<nn::ActorCritic>(nc, par);
  net_->set_precision(precision);
  net_->params().init(cfg_.seed);
  nn::AdamConfig ac;
  ac.lr = float(cfg_.lr);
  ac.weight_decay = float(cfg_.weight_decay);
  ac.max_grad_norm = float(cfg_.grad_clip);
  adam_ = std::make_unique<nn::Adam>(net_->params().layout(), ac);
  obs_norm_ = std::make_unique<nn::ObsNormalizer>(nc.obs);
  intrinsic_ = make_intrinsic_reward(cfg_, nc, R);
  intrinsic_return_.assign(size_t(env1_ - env0_), 0.0);

  rollout_steps_ = cfg_.rollout_steps();
  rows_ = (env1_ - env0_) * L.max_agents;
  const size_t T = size_t(rollout_steps_), G = size_t(rows_), TG = T * G;
  const int heads = net_->heads().num_heads();
  const int sw = net_->state_width();
  Buffers& b = *buf_;
  b.obs.allocate(nc.obs, TG);
  b.actions.assign(TG * heads, 0);
  for (nn::FloatBuffer* f : {&b.logp, &b.value_norm, &b.value, &b.reward, &b.adv, &b.ret, &b.ret_norm})
    f->resize(TG);
  b.mask.assign(TG, 0);
  b.last.assign(TG, 0);
  b.state_p.resize(T / cfg_.bptt * G * sw);
  b.state_v.resize(T / cfg_.bptt * G * sw);
  b.cur_p.resize(G * sw);
  b.cur_v.resize(G * sw);
  b.uniforms.resize(G * heads);
  b.env_actions.resize(G);
  b.episode_start.assign(size_t(env1_ - env0_), 0);
  b.block_of.assign(size_t(env1_ - env0_), 0);
  for (int k = block0_; k < block1_; ++k)
    for (int e = block_env(k); e < block_env(k + 1); ++e) b.block_of[size_t(e - env0_)] = k - block0_;
  b.block_obs_sums.assign(size_t(block1_ - block0_), obs_norm_->make_sums());
  b.episode_obs_sums.assign(size_t(env1_ - env0_), obs_norm_->make_sums());
  next_episode_.assign(cfg_.envs, 0);
}

Trainer::~Trainer() = default;

void Trainer::set_tracing(bool on) {
  tracing_ = on;
  sim_->set_tracing(on);
}

std::vector<batch::TraceEvent> Trainer::take_trace() {
  std::vector<batch::TraceEvent> all = sim_->take_trace();
  all.insert(all.end(), trace_.begin(), trace_.end());
  trace_.clear();
  return all;
}

Clock::time_point Trainer::mark(const char* phase, Clock::time_point begin) {
  const Clock::time_point now = Clock::now();
  if (tracing_) {
    const auto ns = [&](Clock::time_point t) {
      return std::chrono::duration_cast<std::chrono::nanoseconds>(t - sim_->trace_epoch()).count();
    };
    trace_.push_back({phase, ns(begin), ns(now), -1, -1});
  }
  return now;
}

void Trainer::apply_obs_sums() {
  // Every block's sums (rows, then sum and square per feature, key by key), in block order across ranks.
  std::vector<double> mine, all;
  for (const nn::ObsNormalizer::Sums& k : buf_->block_obs_sums) {
    for (int key = 0; key < nn::kNumObsKeys; ++key) {
      mine.push_back(double(k.rows[size_t(key)]));
      mine.insert(mine.end(), k.sum[size_t(key)].begin(), k.sum[size_t(key)].end());
      mine.insert(mine.end(), k.sq[size_t(key)].begin(), k.sq[size_t(key)].end());
    }
  }
  comm_->allgather(mine, all);
  nn::ObsNormalizer::Sums total = obs_norm_->make_sums(), block = total;
  for (size_t at = 0; at < all.size();) {
    for (int key = 0; key < nn::kNumObsKeys; ++key) {
      const size_t f = block.sum[size_t(key)].size();
      block.rows[size_t(key)] = int64_t(all[at++]);
      std::copy_n(all.begin() + ptrdiff_t(at), f, block.sum[size_t(key)].begin());
      at += f;
      std::copy_n(all.begin() + ptrdiff_t(at), f, block.sq[size_t(key)].begin());
      at += f;
    }
    total.merge(block);
  }
  obs_norm_->apply(total);
}

int Trainer::block_env(int k) const {
  return int(int64_t(cfg_.envs) * k / blocks_);
}

void Trainer::restart_envs() {
  sim_->reset(std::span<const int32_t>(next_episode_).subspan(size_t(env0_), size_t(env1_ - env0_)));
  need_restart_ = false;
}

IterationMetrics Trainer::iterate() {
  const Clock::time_point t0 = Clock::now();
  const int64_t agent_steps_before = agent_steps_;
  const int64_t unstable_before = sim_->unstable_resets();
  IterationMetrics m;
  (void)comm_->take_seconds();
  if (need_restart_) restart_envs();
  // In the simulator's arena: its steps and this iteration's other parallel work (inference, learning) then
  // share one set of worker threads, which no longer move between two arenas at every rollout step.
  sim_->arena().execute([&] {
    rollout(m);
    const Clock::time_point t_learn = Clock::now();
    compute_targets(m);
    m.t_targets += seconds_since(t_learn);
    mark("targets", t_learn);
    update(m);
    m.t_learn = seconds_since(t_learn) + m.t_intrinsic;
    // The observation statistics (summed during the rollout) move after the update, so that a rollout and
    // the update of its data see the same normalisation.
    const Clock::time_point t_obs = Clock::now();
    apply_obs_sums();
    m.t_observe += seconds_since(t_obs);
    mark("observation normaliser", t_obs);
  });
  ++iteration_;
  m.iteration = iteration_;
  if (m.iteration == 1) m.precision = cfg_.precision;
  m.agent_steps = agent_steps_;
  m.env_steps = env_steps_;
  m.value_mean = value_norm_.mean();
  m.value_std = value_norm_.std();
  m.unstable_resets = comm_->sum(sim_->unstable_resets() - unstable_before);
  m.t_comm = comm_->take_seconds();
  m.seconds = seconds_since(t0);
  m.t_other = std::max(0.0, m.seconds - m.t_simulate - m.t_observe - m.t_infer - m.t_learn);
  m.steps_per_s = m.seconds > 0 ? double(agent_steps_ - agent_steps_before) / m.seconds : 0.0;
  return m;
}

void Trainer::rollout(IterationMetrics& m) {
  Buffers& b = *buf_;
  const int T = rollout_steps_, E = env1_ - env0_;  // E: this rank's envs (env e here is env env0_ + e)
  b.cur_p.fill_zero();
  b.cur_v.fill_zero();
  b.block_episodes.assign(size_t(block1_ - block0_) * kBlockEpisodeValues, 0.0);
  int64_t simulated = 0;  // agent-steps of real agents, discarded episodes included
  std::fill(b.episode_start.begin(), b.episode_start.end(), 0);
  std::fill(intrinsic_return_.begin(), intrinsic_return_.end(), 0.0);
  for (nn::ObsNormalizer::Sums& k : b.block_obs_sums) k.clear();
  for (nn::ObsNormalizer::Sums& e : b.episode_obs_sums) e.clear();

  for (int t = 0; t < T; ++t) {
    Clock::time_point tp = Clock::now();
    simulated += observe_step(t);
    m.t_observe += seconds_since(tp);
    tp = mark("observe", tp);

    infer_step(t);
    m.t_infer += seconds_since(tp);
    tp = mark("infer", tp);

    sim_->step(b.env_actions);
    m.t_simulate += seconds_since(tp);
    tp = mark("simulate", tp);

    record_step(t);
    m.t_observe += seconds_since(tp);
    mark("observe", tp);
  }

  for (int e = 0; e < E; ++e)
    b.block_obs_sums[size_t(b.block_of[size_t(e)])].merge(b.episode_obs_sums[size_t(e)]);
  if (intrinsic_->after_rollout_runs()) {
    const Clock::time_point tr = Clock::now();
    RolloutRewards rr;
    rr.steps = rollout_steps_;
    rr.rows = rows_;
    rr.agents = sim_->layout().max_agents;
    rr.minibatches = cfg_.minibatches;
    rr.mask = b.mask.data();
    rr.last = b.last.data();
    rr.reward = b.reward.data();
    rr.obs = b.obs.batch();
    rr.add_to_episode = [&](int env, double bonus) {
      b.block_episodes[size_t(b.block_of[size_t(env)]) * kBlockEpisodeValues + kBlockEpisodeValues - 1] +=
          bonus;
    };
    intrinsic_->after_rollout(rr);
    m.t_intrinsic = seconds_since(tr);
    mark(intrinsic_->name(), tr);
  }
  finish_rollout(m, simulated);
}

int64_t Trainer::observe_step(int t) {
  // This step's observations, normalised, and masks into the buffer; the real agents' raw observations into
  // their episode's normaliser sums; the masks, the reset flags, the LSTM states entering a chunk and the
  // step's uniforms.
  Buffers& b = *buf_;
  const nn::ObsShape& shape = net_->config().obs;
  const int G = rows_, A = sim_->layout().max_agents, E = env1_ - env0_;
  const int heads = net_->heads().num_heads();
  const int sw = net_->state_width();
  const size_t row0 = size_t(t) * G;
  const nn::ObsNormView norm = obs_norm_->view();
  const batch::BatchState& s = sim_->state();
  const StepObsView view = StepObsView::of(s);
  b.obs.copy_step(view, G, row0, &norm);
  for (int e = 0; e < E; ++e) {
    const size_t r = size_t(e) * A;
    obs_norm_->add_rows(b.episode_obs_sums[e], view.features_from(r, shape), A, s.agent_exists.data() + r);
  }
  int64_t simulated = 0;
  for (int g = 0; g < G; ++g) {
    // A completed blueprint's remaining steps are absorbed (reward 0, no decision that matters): they
    // leave every loss, as padding agents do; its completing step was the last one learned from.
    b.mask[row0 + g] = s.task_complete[size_t(g / A)] != 0 ? 0 : s.agent_exists[g];
    simulated += s.agent_exists[g];
    const bool starts = t == 0 || b.last[row0 - G + g] != 0;
    b.obs.reset[row0 + g] = starts ? 1.0f : 0.0f;
  }
  if (t % cfg_.bptt == 0) {
    const size_t c = size_t(t / cfg_.bptt);
    std::memcpy(b.state_p.data() + c * G * sw, b.cur_p.data(), sizeof(float) * G * sw);
    std::memcpy(b.state_v.data() + c * G * sw, b.cur_v.data(), sizeof(float) * G * sw);
  }
  // The run's stream of uniforms for this step, env by env: this rank's share of it.
  physics::Rng rng(cfg_.seed ^ kActionStream, uint64_t(iteration_), uint64_t(t));
  for (int64_t i = 0; i < int64_t(env0_) * A * heads; ++i) (void)rng.next_u64();
  for (int i = 0; i < G * heads; ++i) b.uniforms[i] = uniform_float(rng);
  return simulated;
}

void Trainer::infer_step(int t) {
  Buffers& b = *buf_;
  const int G = rows_;
  const size_t row0 = size_t(t) * G;
  const int heads = net_->heads().num_heads();
  const double vmean = value_norm_.mean(), vstd = value_norm_.std();
  nn::ActorCritic::ActOutputs out;
  out.actions = b.actions.data() + row0 * heads;
  out.logp = b.logp.data() + row0;
  out.value = b.value_norm.data() + row0;
  net_->act(nn::ObsNormView::identity(), b.obs.batch().rows_from(row0, net_->config().obs), G, b.cur_p.data(),
            b.cur_v.data(), b.uniforms.data(), out);
  for (int g = 0; g < G; ++g) {
    const int32_t* a = out.actions + size_t(g) * heads;
    b.env_actions[g] = {uint8_t(a[0]), uint8_t(a[1]), uint8_t(a[2]), uint8_t(a[3]), uint8_t(a[4])};
    b.value[row0 + g] = float(b.value_norm[row0 + g] * vstd + vmean);
  }
}

void Trainer::record_step(int t) {
  Buffers& b = *buf_;
  const batch::BatchState& s = sim_->state();
  const batch::Layout& L = sim_->layout();
  const int T = rollout_steps_, G = rows_, A = L.max_agents, E = env1_ - env0_;
  const size_t row0 = size_t(t) * G;
  // The reward trained on: the game's, scaled, plus the intrinsic reward of the state the step reached
  // (after an episode's last step: the next episode's first state, which the auto-reset put in its place).
  const float extrinsic = float(cfg_.extrinsic_coef);
  for (int e = 0; e < E; ++e) {
    float bonus = 0.0f;
    const bool absorbed = s.task_complete[e] != 0 && b.mask[row0 + size_t(e) * A] == 0;
    if (!absorbed) {  // a completed blueprint's absorbed steps visit nothing
      bonus = intrinsic_->step_bonus(s, L, e, env0_ + e);
      intrinsic_return_[size_t(e)] += bonus;
    }
    for (int a = 0; a < A; ++a) {
      const size_t r = row0 + size_t(e) * A + a;
      b.reward[r] =
          extrinsic * s.reward[size_t(e) * A + a] + (s.agent_exists[size_t(e) * A + a] ? bonus : 0.0f);
      b.last[r] = (s.done[e] != 0 || t == T - 1 || s.task_complete[e] != 0) ? 1 : 0;
    }
  }
  for (const batch::EpisodeStats& st : sim_->finished()) {
    const int first = b.episode_start[st.env];
    b.episode_start[st.env] = t + 1;
    const int blk = b.block_of[size_t(st.env)];
    if (!st.discarded) b.block_obs_sums[size_t(blk)].merge(b.episode_obs_sums[st.env]);
    b.episode_obs_sums[st.env].clear();
    const double intrinsic = intrinsic_return_[size_t(st.env)];
    intrinsic_return_[size_t(st.env)] = 0.0;
    if (st.discarded) {
      // An episode cut short by numerical trouble has no true end to bootstrap from: its steps in this
      // rollout leave every loss and statistic, as padding agents do.
      for (int u = first; u <= t; ++u) {
        std::fill_n(b.mask.begin() + ptrdiff_t(size_t(u) * G + size_t(st.env) * A), A, uint8_t{0});
      }
      continue;
    }
    const float v[kBlockEpisodeValues] = {1.0f, st.hider_return, st.seeker_return,
#define HNS_EPISODE_VALUE(name, doc) st.name,
                                          HNS_EPISODE_STATS(HNS_EPISODE_VALUE)
#undef HNS_EPISODE_VALUE
                                              float(intrinsic)};
    double* sums = b.block_episodes.data() + size_t(blk) * kBlockEpisodeValues;
    for (int k = 0; k < kBlockEpisodeValues; ++k) sums[k] += v[k];
  }
}

void Trainer::finish_rollout(IterationMetrics& m, int64_t simulated) {
  Buffers& b = *buf_;
  const int T = rollout_steps_, E = env1_ - env0_;
  // Envs that are not at the start of an episode (one was cut short by numerical trouble and restarted
  // mid-rollout) start their next episode before the next rollout, so every rollout starts fresh. Every
  // rank learns every env's next episode (the checkpoint holds them all).
  const batch::BatchState& s = sim_->state();
  std::vector<double> mine(static_cast<size_t>(E), 0.0), all;
  bool restart = false;
  for (int e = 0; e < E; ++e) {
    mine[size_t(e)] = double(s.episode[e] + (s.step_count[e] != 0 ? 1 : 0));
    restart = restart || s.step_count[e] != 0;
  }
  comm_->allgather(mine, all);
  for (int e = 0; e < cfg_.envs; ++e) next_episode_[size_t(e)] = int32_t(all[size_t(e)]);
  need_restart_ = comm_->any(restart) || need_restart_;
  agent_steps_ += comm_->sum(simulated);
  env_steps_ += int64_t(T) * cfg_.envs;
  // Episode statistics: the blocks' sums in block order.
  comm_->allgather(b.block_episodes, all);
  double totals[kBlockEpisodeValues] = {};
  for (size_t k = 0; k < all.size(); k += kBlockEpisodeValues)
    for (int j = 0; j < kBlockEpisodeValues; ++j) totals[j] += all[k + size_t(j)];
  const double episodes = totals[0];
  m.episodes = int(episodes);
  if (episodes > 0) {
    double* dst[kBlockEpisodeValues - 1] = {&m.hider_reward, &m.seeker_reward,
#define HNS_EPISODE_MEAN(name, doc) &m.name,
                                            HNS_EPISODE_STATS(HNS_EPISODE_MEAN)
#undef HNS_EPISODE_MEAN
                                                & m.intrinsic_reward};
    for (int k = 1; k < kBlockEpisodeValues; ++k) *dst[k - 1] = totals[k] / episodes;
  }
}

void Trainer::compute_targets(IterationMetrics& m) {
  Buffers& b = *buf_;
  const int T = rollout_steps_, G = rows_;
  const GaeParams gp{cfg_.gamma, cfg_.lambda};
  // Windowed GAE per agent row (independent rows, so any split gives the same bits).
  tbb::parallel_for(tbb::blocked_range<int>(0, G, 16), [&](const tbb::blocked_range<int>& r) {
    std::vector<float> rew(T), val(T + 1, 0.0f), adv(T), ret(T);
    std::vector<uint8_t> last(T);
    for (int g = r.begin(); g < r.end(); ++g) {
      for (int t = 0; t < T; ++t) {
        const size_t i = size_t(t) * G + g;
        rew[t] = b.reward[i];
        val[t] = b.value[i];
        last[t] = b.last[i];
      }
      gae_window(rew, val, last, gp, adv, ret);
      for (int t = 0; t < T; ++t) {
        const size_t i = size_t(t) * G + g;
        b.adv[i] = adv[t];
        b.ret[i] = ret[t];
      }
    }
  });
  // Moments over the real agent-steps, per update block (its rows step by step, agent row by agent row), then
  // the blocks' in block order: n, returns and their squares, residuals (return - value) and their squares,
  // advantages and their squares.
  constexpr int kMoments = 7;
  const int A = G / (env1_ - env0_);
  std::vector<double> mine(size_t(block1_ - block0_) * kMoments, 0.0), all;
  for (int k = block0_; k < block1_; ++k) {
    double* mo = mine.data() + size_t(k - block0_) * kMoments;
    const int g0 = (block_env(k) - env0_) * A, g1 = (block_env(k + 1) - env0_) * A;
    for (int t = 0; t < T; ++t) {
      for (int g = g0; g < g1; ++g) {
        const size_t i = size_t(t) * G + g;
        if (b.mask[i] == 0) continue;
        const double ret = b.ret[i], res = double(b.ret[i]) - double(b.value[i]), adv = b.adv[i];
        mo[0] += 1, mo[1] += ret, mo[2] += ret * ret, mo[3] += res, mo[4] += res * res;
        mo[5] += adv, mo[6] += adv * adv;
      }
    }
  }
  comm_->allgather(mine, all);
  double mo[kMoments] = {};
  for (size_t k = 0; k < all.size(); k += kMoments)
    for (int j = 0; j < kMoments; ++j) mo[j] += all[k + size_t(j)];
  const double n = mo[0];
  const size_t TG = size_t(T) * G;
  m.explained_variance = 0.0;
  if (n > 0) {
    const double var_t = mo[2] / n - (mo[1] / n) * (mo[1] / n);
    const double var_r = mo[4] / n - (mo[3] / n) * (mo[3] / n);
    m.explained_variance = var_t > 1e-12 ? 1.0 - var_r / var_t : 0.0;
    value_norm_.update(mo[1] / n, mo[2] / n);
  }
  const double vm = value_norm_.mean(), inv = 1.0 / value_norm_.std();
  for (size_t i = 0; i < TG; ++i) b.ret_norm[i] = float((b.ret[i] - vm) * inv);
  if (n > 0) {
    const double mean = mo[5] / n;
    zscore_with(b.adv.span(), b.mask, mean, std::sqrt(std::max(0.0, mo[6] / n - mean * mean)));
  }
}

void Trainer::update(IterationMetrics& m) {
  Buffers& b = *buf_;
  const int64_t n_chunks = comm_->sum(collect_chunks());
  if (n_chunks == 0) return;
  const int minibatches = cfg_.minibatches_for(n_chunks);
  size_minibatch(minibatches);
  UpdateSums sums;
  for (int epoch = 0; epoch < cfg_.epochs; ++epoch) {
    for (int k = 0; k < block1_ - block0_; ++k) {
      std::vector<int32_t>& list = b.block_chunks[size_t(k)];
      physics::Rng rng(cfg_.seed ^ kShuffleStream, uint64_t(iteration_),
                       (uint64_t(epoch) << 32) | uint64_t(block0_ + k));
      for (int i = int(list.size()) - 1; i > 0; --i) std::swap(list[i], list[rng.uniform_int(0, i + 1)]);
    }
    for (int mb = 0; mb < minibatches; ++mb) {
      const Clock::time_point t_gather = Clock::now();
      const int64_t local_total = gather_minibatch(mb, minibatches);
      m.t_targets += seconds_since(t_gather);
      const Clock::time_point tp = mark("gather", t_gather);
      const int64_t total = comm_->sum(local_total);
      if (total == 0) continue;
      train_minibatch(m, sums, epoch, mb, total, tp);
    }
  }
  if (sums.stats[kCount] > 0) {
    m.policy_loss = sums.stats[kPolicyLoss] / sums.stats[kCount];
    m.value_loss = sums.stats[kValueLoss] / sums.stats[kCount];
    m.entropy = sums.stats[kEntropy] / sums.stats[kCount];
    m.approx_kl = sums.stats[kKl] / sums.stats[kCount];
    m.clip_frac = sums.stats[kClipped] / sums.stats[kCount];
  }
  if (sums.updates > 0) m.grad_norm = sums.grad_norm / sums.updates;
}

int64_t Trainer::collect_chunks() {
  // Chunks holding at least one real agent-step, per update block of this rank's envs (the gradient groups:
  // each block's share of a minibatch is summed in order, the blocks in block order, across ranks too).
  Buffers& b = *buf_;
  const int G = rows_, bptt = cfg_.bptt, chunks_per_row = rollout_steps_ / bptt;
  const int A = G / (env1_ - env0_);
  const int K = block1_ - block0_;
  b.block_chunks.resize(size_t(K));
  int64_t local_chunks = 0;
  for (int k = 0; k < K; ++k) {
    std::vector<int32_t>& list = b.block_chunks[size_t(k)];
    list.clear();
    const int g0 = (block_env(block0_ + k) - env0_) * A, g1 = (block_env(block0_ + k + 1) - env0_) * A;
    for (int c = 0; c < chunks_per_row; ++c) {
      for (int g = g0; g < g1; ++g) {
        bool any = false;
        for (int j = 0; j < bptt && !any; ++j) any = b.mask[size_t(c * bptt + j) * G + g] != 0;
        if (any) list.push_back(c * G + g);
      }
    }
    local_chunks += int64_t(list.size());
  }
  return local_chunks;
}

void Trainer::size_minibatch(int minibatches) {
  Buffers& b = *buf_;
  const int bptt = cfg_.bptt, heads = net_->heads().num_heads(), sw = net_->state_width();
  int max_seq = 0;
  for (const std::vector<int32_t>& list : b.block_chunks)
    max_seq += (int(list.size()) + minibatches - 1) / minibatches;
  if (b.mb_mask.size() < size_t(max_seq) * bptt) {  // grows only: the valid chunk count varies
    const size_t rows = size_t(max_seq) * bptt;
    b.mb_index.assign(rows, 0);
    b.mb_actions.assign(rows * heads, 0);
    b.mb_logp.resize(rows);
    b.mb_adv.resize(rows);
    b.mb_ret.resize(rows);
    b.mb_mask.assign(rows, 0);
    b.mb_state_p.resize(size_t(max_seq) * sw);
    b.mb_state_v.resize(size_t(max_seq) * sw);
  }
}

int64_t Trainer::gather_minibatch(int mb, int minibatches) {
  Buffers& b = *buf_;
  const int G = rows_, bptt = cfg_.bptt, heads = net_->heads().num_heads(), sw = net_->state_width();
  // Block k's share: its chunks [n_k mb / M, n_k (mb + 1) / M).
  b.mb_chunks.clear();
  b.mb_groups.assign(1, 0);
  for (const std::vector<int32_t>& list : b.block_chunks) {
    const int64_t n = int64_t(list.size());
    b.mb_chunks.insert(b.mb_chunks.end(), list.begin() + n * mb / minibatches,
                       list.begin() + n * (mb + 1) / minibatches);
    b.mb_groups.push_back(int(b.mb_chunks.size()));
  }
  const int S = int(b.mb_chunks.size());
  // The chunks' rows, sequence-major; their targets and entering states gathered.
  tbb::parallel_for(tbb::blocked_range<int>(0, S, 8), [&](const tbb::blocked_range<int>& r) {
    for (int k = r.begin(); k < r.end(); ++k) {
      const int id = b.mb_chunks[size_t(k)];
      const int c = id / G, g = id % G;
      std::memcpy(b.mb_state_p.data() + size_t(k) * sw, b.state_p.data() + (size_t(c) * G + g) * sw,
                  sizeof(float) * sw);
      std::memcpy(b.mb_state_v.data() + size_t(k) * sw, b.state_v.data() + (size_t(c) * G + g) * sw,
                  sizeof(float) * sw);
      for (int j = 0; j < bptt; ++j) {
        const size_t src = size_t(c * bptt + j) * G + g, dst = size_t(k) * bptt + j;
        b.mb_index[dst] = int32_t(src);
        std::memcpy(b.mb_actions.data() + dst * heads, b.actions.data() + src * heads,
                    sizeof(int32_t) * heads);
        b.mb_logp[dst] = b.logp[src];
        b.mb_adv[dst] = b.adv[src];
        b.mb_ret[dst] = b.ret_norm[src];
        b.mb_mask[dst] = b.mask[src];
      }
    }
  });
  int64_t local_total = 0;
  for (int i = 0; i < S * bptt; ++i) local_total += b.mb_mask[i];
  return local_total;
}

void Trainer::train_minibatch(IterationMetrics& m, UpdateSums& sums, int epoch, int mb, int64_t total,
                              Clock::time_point tp) {
  Buffers& b = *buf_;
  const int S = int(b.mb_chunks.size());
  const bool poison = cfg_.inject_nan_at > 0 && iteration_ + 1 == cfg_.inject_nan_at;
  const nn::CategoricalHeads& hd = net_->heads();
  const PpoMinibatch mbatch{.actions = b.mb_actions.data(),
                            .old_logp = b.mb_logp.data(),
                            .advantages = b.mb_adv.data(),
                            .returns = b.mb_ret.data(),
                            .mask = b.mb_mask.data(),
                            .clip = float(cfg_.clip),
                            .entropy_coef = cfg_.entropy_coef,
                            .value_coef = cfg_.value_coef,
                            .inv_total = 1.0 / double(total)};
  nn::LossFn loss = [&](const nn::ChunkOutputs& out, const nn::ChunkGrads& g, std::span<double> st) {
    ppo_chunk_loss(hd, mbatch, out, g, b.loss_scratch.local(), st);
    if (poison) g.d_value[0] = std::numeric_limits<float>::quiet_NaN();
  };
  nn::ObsBatch mb_obs = b.obs.batch();
  mb_obs.index = b.mb_index.data();
  net_->compute_groups(nn::ObsNormView::identity(), mb_obs, S, cfg_.bptt, b.mb_state_p.data(),
                       b.mb_state_v.data(), loss, kNumStats, b.mb_groups);
  m.t_backward += seconds_since(tp);
  tp = mark("forward+backward", tp);
  // The minibatch's gradient: every block's group in block order, through the ranks in rank order; its
  // statistics: every chunk's in chunk order.
  float* grads = net_->params().grads();
  comm_->chain_sum(
      net_->params().buffer_floats(),
      [&](size_t begin, size_t end, const float* before, float* out) {
        tbb::parallel_for(tbb::blocked_range<size_t>(begin, end, 1 << 14),
                          [&](const tbb::blocked_range<size_t>& r) {
                            net_->sum_groups(r.begin(), r.end(),
                                             before == nullptr ? nullptr : before + (r.begin() - begin), out);
                          });
      },
      grads);
  std::vector<double>& all_stats = b.all_chunk_stats;
  comm_->allgather(net_->chunk_stats(), all_stats);
  double st[kNumStats] = {};
  for (size_t c = 0; c < all_stats.size(); c += kNumStats)
    for (int k = 0; k < kNumStats; ++k) st[k] += all_stats[c + size_t(k)];
  m.t_backward += seconds_since(tp);
  tp = Clock::now();
  const nn::AdamStepInfo info = adam_->step(net_->params().values(), grads);
  m.t_optimizer += seconds_since(tp);
  mark("optimizer", tp);
  bool finite = info.applied;
  for (double v : st) finite = finite && std::isfinite(v);
  if (!finite) {
    throw NumericalError("iteration " + std::to_string(iteration_ + 1) + ", epoch " +
                         std::to_string(epoch + 1) + ", minibatch " + std::to_string(mb + 1) +
                         ": the loss or its gradient is not finite" + " (gradient norm " +
                         std::to_string(info.grad_norm) + ")");
  }
  for (int k = 0; k < kNumStats; ++k) sums.stats[k] += st[k];
  sums.grad_norm += info.grad_norm;
  ++sums.updates;
}

}  // namespace hns::ppo
