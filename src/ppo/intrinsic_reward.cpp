#include "ppo/intrinsic_reward.hpp"

#include <cstring>
#include <span>

#include "ppo/intrinsic.hpp"
#include "ppo/rnd.hpp"

namespace hns::ppo {
namespace {

// ---- none

class NoBonus final : public IntrinsicReward {
 public:
  const char* name() const override { return "none"; }
  float step_bonus(const batch::BatchState&, const batch::Layout&, int, int) override { return 0.0f; }
  bool after_rollout_runs() const override { return false; }
  void after_rollout(const RolloutRewards&) override {}
  void save(CheckpointWriter&) const override {}
  void restore(const IntrinsicState&) override {}
};

class NoState final : public IntrinsicState {
 public:
  void check(const std::function<void(const std::string&)>&) const override {}
};

// ---- count: 0.1 / sqrt(N) for the N-th visit of the env's hashed state

// Checkpoint section: per env of the run, in key order, its keys (u64 array) and their counts (u32 array).
class CountState final : public IntrinsicState {
 public:
  std::vector<std::vector<std::pair<uint64_t, uint32_t>>> per_env;
  void check(const std::function<void(const std::string&)>&) const override {}
};

class CountBonus final : public IntrinsicReward {
 public:
  explicit CountBonus(const TrainConfig& cfg)
      : hasher_(parse_count_state(cfg.count_state), cfg.seed), counts_(cfg.envs, cfg.count_scale) {}
  const char* name() const override { return "count"; }
  float step_bonus(const batch::BatchState& s, const batch::Layout& layout, int env, int run_env) override {
    return counts_.visit(run_env, hasher_.key(s, layout, env));
  }
  bool after_rollout_runs() const override { return false; }
  void after_rollout(const RolloutRewards&) override {}
  void save(CheckpointWriter& w) const override {
    for (const auto& env : counts_.sorted()) {
      std::vector<uint64_t> keys(env.size());
      std::vector<uint32_t> n(env.size());
      for (size_t i = 0; i < env.size(); ++i) keys[i] = env[i].first, n[i] = env[i].second;
      w.put_array(keys.data(), keys.size());
      w.put_array(n.data(), n.size());
    }
  }
  static std::unique_ptr<IntrinsicState> read(CheckpointReader& r, const TrainConfig& saved) {
    auto st = std::make_unique<CountState>();
    st->per_env.resize(size_t(saved.envs));
    for (auto& env : st->per_env) {
      const uint64_t n = r.peek_length();
      std::vector<uint64_t> keys(n);
      std::vector<uint32_t> counts(n);
      r.get_array(keys.data(), n, "the state counts");
      r.get_array(counts.data(), n, "the state counts");
      env.resize(n);
      for (size_t i = 0; i < n; ++i) env[i] = {keys[i], counts[i]};
    }
    return st;
  }
  void restore(const IntrinsicState& state) override {
    counts_.restore(dynamic_cast<const CountState&>(state).per_env);
  }

 private:
  CountHasher hasher_;
  StateCounts counts_;
};

// ---- rnd: rnd_scale x the predictor's error on the observation a step reached

// Checkpoint section: the predictor's parameters, Adam's two moments (float arrays) and its step count
// (the target is the seed's).
class RndState final : public IntrinsicState {
 public:
  nn::FloatBuffer values, m, v;
  int64_t steps = 0;
  void check(const std::function<void(const std::string&)>& refuse) const override {
    if (steps < 0)
      refuse("the RND optimiser's step count is " + std::to_string(steps) + " (a count is at least 0)");
    refuse_bad_values(refuse, "the RND predictor", values.data(), values.size(), false);
    refuse_bad_values(refuse, "the RND predictor's first moment", m.data(), m.size(), false);
    refuse_bad_values(refuse, "the RND predictor's second moment", v.data(), v.size(), true);
  }
};

class RndBonus final : public IntrinsicReward {
 public:
  // RND's target and predictor stay fp32 whatever the precision of the policy and value networks.
  RndBonus(const TrainConfig& cfg, const nn::NetConfig& net)
      : rnd_(net, cfg.seed, float(cfg.lr)), scale_(float(cfg.rnd_scale)) {}
  const char* name() const override { return "rnd"; }
  float step_bonus(const batch::BatchState&, const batch::Layout&, int, int) override { return 0.0f; }
  bool after_rollout_runs() const override { return true; }

  // The reward of an agent's step is rnd_scale x the prediction error of the observation it reached within
  // its episode (an episode's last step reaches none: 0), added to the step's reward and, as the mean over
  // the env's real agents, to its episode's intrinsic return. Then the predictor takes `minibatches` Adam
  // steps on the rollout's learned rows (row i in minibatch i mod minibatches), so the states just visited
  // pay less next time.
  void after_rollout(const RolloutRewards& r) override {
    const int T = r.steps, G = r.rows, A = r.agents;
    const size_t rows = size_t(T) * G;
    std::vector<float> err(rows);
    rnd_.errors(nn::ObsNormView::identity(), r.obs, rows, err.data());
    for (int t = 0; t + 1 < T; ++t) {
      for (int g = 0; g < G; ++g) {
        const size_t i = size_t(t) * G + g;
        if (r.mask[i] == 0 || r.last[i] != 0) continue;
        const float bonus = scale_ * err[i + size_t(G)];
        r.reward[i] += bonus;
        const int e = g / A;
        int real = 0;
        for (int a = 0; a < A; ++a) real += r.mask[size_t(t) * G + size_t(e) * A + a];
        r.add_to_episode(e, double(bonus) / real);
      }
    }
    std::vector<std::vector<int32_t>> batches(size_t(r.minibatches));
    int64_t learned = 0;
    for (size_t i = 0; i < rows; ++i) {
      if (r.mask[i] == 0) continue;
      batches[size_t(learned++ % r.minibatches)].push_back(int32_t(i));
    }
    for (const std::vector<int32_t>& mb : batches) rnd_.train(nn::ObsNormView::identity(), r.obs, mb);
  }

  void save(CheckpointWriter& w) const override {
    const size_t rf = rnd_.predictor().buffer_floats();
    w.put_array(rnd_.predictor().values(), rf);
    w.put_array(rnd_.optimizer().m().data(), rf);
    w.put_array(rnd_.optimizer().v().data(), rf);
    w.put(rnd_.optimizer().steps());
  }
  static std::unique_ptr<IntrinsicState> read(CheckpointReader& r, const nn::NetConfig& saved_net) {
    auto st = std::make_unique<RndState>();
    const size_t rf = Rnd::predictor_floats(saved_net);
    st->values.resize(rf);
    st->m.resize(rf);
    st->v.resize(rf);
    r.get_array(st->values.data(), rf, "the RND predictor");
    r.get_array(st->m.data(), rf, "the RND predictor's first moment");
    r.get_array(st->v.data(), rf, "the RND predictor's second moment");
    st->steps = r.get<int64_t>();
    return st;
  }
  void restore(const IntrinsicState& state) override {
    const auto& st = dynamic_cast<const RndState&>(state);
    const size_t rf = rnd_.predictor().buffer_floats();
    if (st.values.size() != rf)
      throw std::logic_error("RndBonus::restore: an RND predictor of another layout");
    std::memcpy(rnd_.predictor().values(), st.values.data(), rf * sizeof(float));
    std::memcpy(rnd_.optimizer().m().data(), st.m.data(), rf * sizeof(float));
    std::memcpy(rnd_.optimizer().v().data(), st.v.data(), rf * sizeof(float));
    rnd_.optimizer().set_steps(st.steps);
  }

 private:
  Rnd rnd_;
  float scale_;
};

// count and rnd keep state that one process owns whole.
void require_one_rank(const std::string& kind, int ranks, const char* why) {
  if (ranks > 1) {
    throw physics::ConfigError("intrinsic = " + kind + " runs in one process (" + std::to_string(ranks) +
                               " ranks given): " + why);
  }
}

}  // namespace

std::unique_ptr<IntrinsicReward> make_intrinsic_reward(const TrainConfig& cfg, const nn::NetConfig& net,
                                                       int ranks) {
  if (cfg.intrinsic == "none") return std::make_unique<NoBonus>();
  if (cfg.intrinsic == "count") {
    require_one_rank(cfg.intrinsic, ranks, "the state counts are per env and saved with the checkpoint");
    return std::make_unique<CountBonus>(cfg);
  }
  if (cfg.intrinsic == "rnd") {
    require_one_rank(cfg.intrinsic, ranks, "its predictor network learns from one rollout");
    return std::make_unique<RndBonus>(cfg, net);
  }
  throw physics::ConfigError("intrinsic: unknown bonus '" + cfg.intrinsic + "' (none, count or rnd)");
}

std::unique_ptr<IntrinsicState> read_intrinsic_state(CheckpointReader& r, const TrainConfig& saved,
                                                     const nn::NetConfig& saved_net) {
  if (saved.intrinsic == "none") return std::make_unique<NoState>();
  if (saved.intrinsic == "count") return CountBonus::read(r, saved);
  if (saved.intrinsic == "rnd") return RndBonus::read(r, saved_net);
  throw std::runtime_error("a checkpoint of a run with intrinsic = '" + saved.intrinsic +
                           "', which this build does not know");
}

}  // namespace hns::ppo
