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

#include "physics/rng.hpp"
#include "ppo/obs_arrays.hpp"
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
  ObsArrays obs;
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
  std::vector<int32_t> episode_start;  // [E] rollout step at which each env's current episode started
  // Observation normaliser sums of the rollout's real agent-steps: per env those of its current episode,
  // added to the rollout's when the episode ends (dropped if it is discarded for numerical trouble, like
  // every other statistic of such an episode), the open ones at the end of the rollout in env order.
  nn::ObsNormalizer::Sums obs_sums;
  std::vector<nn::ObsNormalizer::Sums> episode_obs_sums;         // [E]
  tbb::enumerable_thread_specific<PpoLossScratch> loss_scratch;  // per thread
};

std::string IterationMetrics::to_json() const {
  char buf[2048];
  std::snprintf(
      buf, sizeof buf,
      "{\"iteration\": %lld, \"agent_steps\": %lld, \"env_steps\": %lld, \"seconds\": %.4f, "
      "\"steps_per_s\": %.1f, \"episodes\": %d, \"hider_reward\": %.6g, \"seeker_reward\": %.6g, "
      "\"max_box_move_prep\": %.6g, \"num_box_lock_prep\": %.6g, \"max_ramp_move_prep\": %.6g, "
      "\"num_ramp_lock_prep\": %.6g, \"max_box_move\": %.6g, \"num_box_lock\": %.6g, \"max_ramp_move\": "
      "%.6g, "
      "\"num_ramp_lock\": %.6g, \"policy_loss\": %.6g, \"value_loss\": %.6g, \"entropy\": %.6g, "
      "\"approx_kl\": %.6g, \"clip_frac\": %.6g, \"explained_variance\": %.6g, \"grad_norm\": %.6g, "
      "\"value_mean\": %.6g, \"value_std\": %.6g, \"time_simulate\": %.4f, \"time_observe\": %.4f, "
      "\"time_infer\": %.4f, \"time_learn\": %.4f, \"time_targets\": %.4f, \"time_backward\": %.4f, "
      "\"time_optimizer\": %.4f, \"time_other\": %.4f, "
      "\"unstable_resets\": %lld}",
      static_cast<long long>(iteration), static_cast<long long>(agent_steps),
      static_cast<long long>(env_steps), seconds, steps_per_s, episodes, hider_reward, seeker_reward,
      max_box_move_prep, num_box_lock_prep, max_ramp_move_prep, num_ramp_lock_prep, max_box_move,
      num_box_lock, max_ramp_move, num_ramp_lock, policy_loss, value_loss, entropy, approx_kl, clip_frac,
      explained_variance, grad_norm, value_mean, value_std, t_simulate, t_observe, t_infer, t_learn,
      t_targets, t_backward, t_optimizer, t_other, static_cast<long long>(unstable_resets));
  return buf;
}

Trainer::Trainer(const TrainConfig& config) : cfg_(config), buf_(std::make_unique<Buffers>()) {
  cfg_.validate();
  batch::BatchConfig bc;
  bc.world = cfg_.world();
  bc.num_envs = cfg_.envs;
  bc.threads = cfg_.threads > 0 ? cfg_.threads : tbb::this_task_arena::max_concurrency();
  bc.seed = cfg_.seed;
  sim_ = std::make_unique<batch::BatchSim>(bc);
  const batch::Layout& L = sim_->layout();

  nn::NetConfig nc = nn::net_preset(cfg_.model);
  nc.obs = obs_shape(L);
  nn::ParallelConfig par;
  par.grad_groups = cfg_.grad_groups;
  net_ = std::make_unique<nn::ActorCritic>(nc, par);
  net_->params().init(cfg_.seed);
  nn::AdamConfig ac;
  ac.lr = float(cfg_.lr);
  ac.weight_decay = float(cfg_.weight_decay);
  ac.max_grad_norm = float(cfg_.grad_clip);
  adam_ = std::make_unique<nn::Adam>(net_->params().layout(), ac);
  obs_norm_ = std::make_unique<nn::ObsNormalizer>(nc.obs);

  rollout_steps_ = cfg_.rollout_steps();
  rows_ = cfg_.envs * L.max_agents;
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
  b.episode_start.assign(size_t(cfg_.envs), 0);
  b.obs_sums = obs_norm_->make_sums();
  b.episode_obs_sums.assign(size_t(cfg_.envs), b.obs_sums);
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

void Trainer::restart_envs() {
  sim_->reset(next_episode_);
  need_restart_ = false;
}

IterationMetrics Trainer::iterate() {
  const Clock::time_point t0 = Clock::now();
  const int64_t agent_steps_before = agent_steps_;
  const int64_t unstable_before = sim_->unstable_resets();
  IterationMetrics m;
  if (need_restart_) restart_envs();
  const int threads = cfg_.threads > 0 ? cfg_.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  arena.execute([&] {
    rollout(m);
    const Clock::time_point t_learn = Clock::now();
    compute_targets(m);
    m.t_targets += seconds_since(t_learn);
    mark("targets", t_learn);
    update(m);
    m.t_learn = seconds_since(t_learn);
    // The observation statistics (summed during the rollout) move after the update, so that a rollout and
    // the update of its data see the same normalisation.
    const Clock::time_point t_obs = Clock::now();
    obs_norm_->apply(buf_->obs_sums);
    m.t_observe += seconds_since(t_obs);
    mark("observation normaliser", t_obs);
  });
  ++iteration_;
  m.iteration = iteration_;
  m.agent_steps = agent_steps_;
  m.env_steps = env_steps_;
  m.value_mean = value_norm_.mean();
  m.value_std = value_norm_.std();
  m.unstable_resets = sim_->unstable_resets() - unstable_before;
  m.seconds = seconds_since(t0);
  m.t_other = std::max(0.0, m.seconds - m.t_simulate - m.t_observe - m.t_infer - m.t_learn);
  m.steps_per_s = m.seconds > 0 ? double(agent_steps_ - agent_steps_before) / m.seconds : 0.0;
  return m;
}

void Trainer::rollout(IterationMetrics& m) {
  Buffers& b = *buf_;
  const batch::Layout& L = sim_->layout();
  const nn::ObsShape& shape = net_->config().obs;
  const int T = rollout_steps_, G = rows_, A = L.max_agents, E = cfg_.envs;
  const int heads = net_->heads().num_heads();
  const int sw = net_->state_width();
  const nn::ObsNormView norm = obs_norm_->view();
  const double vmean = value_norm_.mean(), vstd = value_norm_.std();
  b.cur_p.fill_zero();
  b.cur_v.fill_zero();
  double sum_hider = 0, sum_seeker = 0;
  double stat_sums[8] = {};
  int episodes = 0;
  int64_t simulated = 0;  // agent-steps of real agents, discarded episodes included
  std::fill(b.episode_start.begin(), b.episode_start.end(), 0);
  b.obs_sums.clear();
  for (nn::ObsNormalizer::Sums& e : b.episode_obs_sums) e.clear();
  const size_t na = size_t(shape.num_other_agents());
  const size_t per_agent[5] = {size_t(shape.self_features), size_t(shape.lidar_rays),
                               na * shape.agent_features, size_t(shape.max_boxes) * shape.box_features,
                               size_t(shape.max_ramps) * shape.ramp_features};

  for (int t = 0; t < T; ++t) {
    const size_t row0 = size_t(t) * G;
    // Observe: this step's observations, normalised, and masks into the buffer; the real agents' raw
    // observations into their episode's normaliser sums.
    Clock::time_point tp = Clock::now();
    const batch::BatchState& s = sim_->state();
    ObsArrays& o = b.obs;
    const StepObsView view = StepObsView::of(s);
    o.copy_step(view, shape, G, row0, &norm);
    for (int e = 0; e < E; ++e) {
      const size_t r = size_t(e) * A;
      const auto at = [&](const float* p, int key) { return p == nullptr ? p : p + r * per_agent[key]; };
      obs_norm_->add_rows(b.episode_obs_sums[e], at(view.self, 0), at(view.lidar, 1), at(view.agents, 2),
                          at(view.boxes, 3), at(view.ramps, 4), A, s.agent_exists.data() + r);
    }
    for (int g = 0; g < G; ++g) {
      b.mask[row0 + g] = s.agent_exists[g];
      simulated += s.agent_exists[g];
      const bool starts = t == 0 || b.last[row0 - G + g] != 0;
      o.reset[row0 + g] = starts ? 1.0f : 0.0f;
    }
    if (t % cfg_.bptt == 0) {
      const size_t c = size_t(t / cfg_.bptt);
      std::memcpy(b.state_p.data() + c * G * sw, b.cur_p.data(), sizeof(float) * G * sw);
      std::memcpy(b.state_v.data() + c * G * sw, b.cur_v.data(), sizeof(float) * G * sw);
    }
    physics::Rng rng(cfg_.seed ^ kActionStream, uint64_t(iteration_), uint64_t(t));
    for (int i = 0; i < G * heads; ++i) b.uniforms[i] = uniform_float(rng);
    m.t_observe += seconds_since(tp);
    tp = mark("observe", tp);

    // Infer.
    nn::ActorCritic::ActOutputs out;
    out.actions = b.actions.data() + row0 * heads;
    out.logp = b.logp.data() + row0;
    out.value = b.value_norm.data() + row0;
    net_->act(nn::ObsNormView::identity(), o.batch().rows_from(row0, shape), G, b.cur_p.data(),
              b.cur_v.data(), b.uniforms.data(), out);
    for (int g = 0; g < G; ++g) {
      const int32_t* a = out.actions + size_t(g) * heads;
      b.env_actions[g] = {uint8_t(a[0]), uint8_t(a[1]), uint8_t(a[2]), uint8_t(a[3]), uint8_t(a[4])};
      b.value[row0 + g] = float(b.value_norm[row0 + g] * vstd + vmean);
    }
    m.t_infer += seconds_since(tp);
    tp = mark("infer", tp);

    // Simulate.
    sim_->step(b.env_actions);
    m.t_simulate += seconds_since(tp);
    tp = mark("simulate", tp);

    for (int e = 0; e < E; ++e) {
      for (int a = 0; a < A; ++a) {
        const size_t r = row0 + size_t(e) * A + a;
        b.reward[r] = s.reward[size_t(e) * A + a];
        b.last[r] = (s.done[e] != 0 || t == T - 1) ? 1 : 0;
      }
    }
    for (const batch::EpisodeStats& st : sim_->finished()) {
      const int first = b.episode_start[st.env];
      b.episode_start[st.env] = t + 1;
      if (!st.discarded) b.obs_sums.merge(b.episode_obs_sums[st.env]);
      b.episode_obs_sums[st.env].clear();
      if (st.discarded) {
        // An episode cut short by numerical trouble has no true end to bootstrap from: its steps in this
        // rollout leave every loss and statistic, as padding agents do.
        for (int u = first; u <= t; ++u) {
          std::fill_n(b.mask.begin() + ptrdiff_t(size_t(u) * G + size_t(st.env) * A), A, uint8_t{0});
        }
        continue;
      }
      ++episodes;
      sum_hider += st.hider_return;
      sum_seeker += st.seeker_return;
      const float v[8] = {st.max_box_move_prep,  st.num_box_lock_prep, st.max_ramp_move_prep,
                          st.num_ramp_lock_prep, st.max_box_move,      st.num_box_lock,
                          st.max_ramp_move,      st.num_ramp_lock};
      for (int k = 0; k < 8; ++k) stat_sums[k] += v[k];
    }
    m.t_observe += seconds_since(tp);
    mark("observe", tp);
  }

  for (const nn::ObsNormalizer::Sums& e : b.episode_obs_sums) b.obs_sums.merge(e);

  // Envs that are not at the start of an episode (one was cut short by numerical trouble and restarted
  // mid-rollout) start their next episode before the next rollout, so every rollout starts fresh.
  const batch::BatchState& s = sim_->state();
  for (int e = 0; e < E; ++e) {
    next_episode_[e] = s.episode[e] + (s.step_count[e] != 0 ? 1 : 0);
    need_restart_ = need_restart_ || s.step_count[e] != 0;
  }
  agent_steps_ += simulated;
  env_steps_ += int64_t(T) * E;
  m.episodes = episodes;
  if (episodes > 0) {
    m.hider_reward = sum_hider / episodes;
    m.seeker_reward = sum_seeker / episodes;
    double* dst[8] = {&m.max_box_move_prep,  &m.num_box_lock_prep, &m.max_ramp_move_prep,
                      &m.num_ramp_lock_prep, &m.max_box_move,      &m.num_box_lock,
                      &m.max_ramp_move,      &m.num_ramp_lock};
    for (int k = 0; k < 8; ++k) *dst[k] = stat_sums[k] / episodes;
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
  const size_t TG = size_t(T) * G;
  m.explained_variance = explained_variance(b.value.span(), b.ret.span(), b.mask);
  double sum = 0, sq = 0;
  int64_t n = 0;
  for (size_t i = 0; i < TG; ++i) {
    if (b.mask[i] == 0) continue;
    sum += b.ret[i];
    sq += double(b.ret[i]) * b.ret[i];
    ++n;
  }
  if (n > 0) value_norm_.update(sum / n, sq / n);
  const double vm = value_norm_.mean(), inv = 1.0 / value_norm_.std();
  for (size_t i = 0; i < TG; ++i) b.ret_norm[i] = float((b.ret[i] - vm) * inv);
  zscore(b.adv.span(), b.mask);
}

void Trainer::update(IterationMetrics& m) {
  Buffers& b = *buf_;
  const int T = rollout_steps_, G = rows_, bptt = cfg_.bptt;
  const int heads = net_->heads().num_heads();
  const int sw = net_->state_width();
  const int chunks_per_row = T / bptt;

  // Chunks holding at least one real agent-step, per update block of envs (the gradient groups: each block's
  // share of a minibatch is summed in order, the blocks in block order).
  const int E = cfg_.envs, A = G / E;
  const int K = std::min(cfg_.grad_groups, E);
  b.block_chunks.resize(size_t(K));
  int n_chunks = 0;
  for (int k = 0; k < K; ++k) {
    std::vector<int32_t>& list = b.block_chunks[size_t(k)];
    list.clear();
    const int g0 = int(int64_t(E) * k / K) * A, g1 = int(int64_t(E) * (k + 1) / K) * A;
    for (int c = 0; c < chunks_per_row; ++c) {
      for (int g = g0; g < g1; ++g) {
        bool any = false;
        for (int j = 0; j < bptt && !any; ++j) any = b.mask[size_t(c * bptt + j) * G + g] != 0;
        if (any) list.push_back(c * G + g);
      }
    }
    n_chunks += int(list.size());
  }
  if (n_chunks == 0) return;
  const int minibatches = cfg_.minibatches_for(n_chunks);
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

  const float clip = float(cfg_.clip);
  const double ent_coef = cfg_.entropy_coef, v_coef = cfg_.value_coef;
  const nn::CategoricalHeads& hd = net_->heads();
  nn::ObsBatch mb_obs = b.obs.batch();
  mb_obs.index = b.mb_index.data();
  double sums[kNumStats] = {};
  double grad_norm_sum = 0;
  int updates = 0;

  for (int epoch = 0; epoch < cfg_.epochs; ++epoch) {
    for (int k = 0; k < K; ++k) {
      std::vector<int32_t>& list = b.block_chunks[size_t(k)];
      physics::Rng rng(cfg_.seed ^ kShuffleStream, uint64_t(iteration_),
                       (uint64_t(epoch) << 32) | uint64_t(k));
      for (int i = int(list.size()) - 1; i > 0; --i) std::swap(list[i], list[rng.uniform_int(0, i + 1)]);
    }
    for (int mb = 0; mb < minibatches; ++mb) {
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
      const Clock::time_point t_gather = Clock::now();
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
      int64_t total = 0;
      for (int i = 0; i < S * bptt; ++i) total += b.mb_mask[i];
      m.t_targets += seconds_since(t_gather);
      Clock::time_point tp = mark("gather", t_gather);
      if (total == 0) continue;
      const double inv_total = 1.0 / double(total);
      const bool poison = cfg_.inject_nan_at > 0 && iteration_ + 1 == cfg_.inject_nan_at;

      const PpoMinibatch mbatch{.actions = b.mb_actions.data(),
                                .old_logp = b.mb_logp.data(),
                                .advantages = b.mb_adv.data(),
                                .returns = b.mb_ret.data(),
                                .mask = b.mb_mask.data(),
                                .clip = clip,
                                .entropy_coef = ent_coef,
                                .value_coef = v_coef,
                                .inv_total = inv_total};
      nn::LossFn loss = [&](const nn::ChunkOutputs& out, const nn::ChunkGrads& g, std::span<double> st) {
        ppo_chunk_loss(hd, mbatch, out, g, b.loss_scratch.local(), st);
        if (poison) g.d_value[0] = std::numeric_limits<float>::quiet_NaN();
      };
      double st[kNumStats] = {};
      float* grads = net_->params().grads();
      net_->forward_backward(nn::ObsNormView::identity(), mb_obs, S, bptt, b.mb_state_p.data(),
                             b.mb_state_v.data(), loss, std::span<double>(st, kNumStats), grads, b.mb_groups);
      m.t_backward += seconds_since(tp);
      tp = mark("forward+backward", tp);
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
      for (int k = 0; k < kNumStats; ++k) sums[k] += st[k];
      grad_norm_sum += info.grad_norm;
      ++updates;
    }
  }
  if (sums[kCount] > 0) {
    m.policy_loss = sums[kPolicyLoss] / sums[kCount];
    m.value_loss = sums[kValueLoss] / sums[kCount];
    m.entropy = sums[kEntropy] / sums[kCount];
    m.approx_kl = sums[kKl] / sums[kCount];
    m.clip_frac = sums[kClipped] / sums[kCount];
  }
  if (updates > 0) m.grad_norm = grad_norm_sum / updates;
}

}  // namespace hns::ppo
