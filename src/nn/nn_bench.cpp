#include "nn/nn_bench.hpp"

#include "nn/adam.hpp"
#include "nn/bf16_gemm.hpp"
#include "nn/obs_store.hpp"

#include <oneapi/tbb/global_control.h>
#include <oneapi/tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <vector>

namespace hns::nn {
namespace {

constexpr int kMaxLossRows = 64;  // loss scratch rows on the stack

}  // namespace

ObsStore synthetic_obs(const ObsShape& s, const MaskDensity& d, int rows, uint64_t seed) {
  ObsStore obs(s, size_t(rows));
  InitRng rng(seed, 1);
  auto fill = [&](FloatBuffer& v, double lo, double hi) {
    for (float& x : v.span()) x = static_cast<float>(lo + (hi - lo) * rng.uniform());
  };
  auto mask = [&](FloatBuffer& v, double p) {
    for (float& x : v.span()) x = rng.uniform() < p ? 1.0f : 0.0f;
  };
  // present ~ p_present (no draws when 1: the default inputs are those of earlier versions); seen ~ p_seen
  // among the present.
  auto present_mask = [&](FloatBuffer& present, FloatBuffer& seen, double p_present) {
    if (p_present >= 1.0) {
      std::fill(present.span().begin(), present.span().end(), 1.0f);
    } else {
      mask(present, p_present);
    }
    for (size_t i = 0; i < seen.size(); ++i) seen[i] *= present[i];
  };
  fill(obs.self, -3.0, 3.0);
  fill(obs.lidar, 0.0, 6.0);
  fill(obs.agents, -3.0, 3.0);
  fill(obs.boxes, -3.0, 3.0);
  fill(obs.ramps, -3.0, 3.0);
  mask(obs.agents_seen, d.agents_seen);
  mask(obs.boxes_seen, d.boxes_seen);
  mask(obs.ramps_seen, d.ramps_seen);
  present_mask(obs.agents_present, obs.agents_seen, d.agents_present);
  present_mask(obs.boxes_present, obs.boxes_seen, d.boxes_present);
  present_mask(obs.ramps_present, obs.ramps_seen, d.ramps_present);
  const size_t nb = size_t(s.max_boxes);
  if (d.alternate_last_box && nb > 0)
    for (size_t i = 0; i < size_t(rows); i += 2)
      obs.boxes_present[i * nb + nb - 1] = obs.boxes_seen[i * nb + nb - 1] = 0.0f;
  mask(obs.reset, 0.05);
  return obs;
}

namespace {

// Median seconds per call of f, after one warm-up call, over at least 3 calls and min_seconds.
template <class F>
double median_seconds(double min_seconds, F&& f) {
  using Clock = std::chrono::steady_clock;
  f();
  std::vector<double> times;
  const auto start = Clock::now();
  while (times.size() < 3 || std::chrono::duration<double>(Clock::now() - start).count() < min_seconds) {
    const auto t0 = Clock::now();
    f();
    times.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

// Inference: one step for infer_agents agents.
void bench_inference(const NnBenchOptions& o, const ActorCritic& ac, const ObsNormalizer& norm,
                     NnBenchResult& res) {
  const NetConfig& cfg = ac.config();
  const int nh = ac.heads().num_heads();
  const int sw = ac.state_width();
  const ObsStore obs = synthetic_obs(cfg.obs, o.masks, o.infer_agents, o.seed + 2);
  std::vector<float> ps(static_cast<size_t>(o.infer_agents) * sw, 0.0f), vs(ps.size(), 0.0f);
  std::vector<float> uniforms(static_cast<size_t>(o.infer_agents) * nh);
  InitRng rng(o.seed, 3);
  for (auto& u : uniforms) u = static_cast<float>(rng.uniform());
  std::vector<int32_t> actions(uniforms.size());
  std::vector<float> logp(o.infer_agents), value(o.infer_agents);
  res.infer_seconds = median_seconds(o.min_seconds, [&] {
    ac.act(norm.view(), obs.batch(), o.infer_agents, ps.data(), vs.data(), uniforms.data(),
           {actions.data(), logp.data(), value.data(), nullptr});
  });
  res.infer_flops_per_agent_step = ac.forward_flops(o.infer_agents) / o.infer_agents;
  res.infer_agent_steps_per_s = o.infer_agents / res.infer_seconds;
  res.infer_gflops = res.infer_flops_per_agent_step * res.infer_agent_steps_per_s * 1e-9;
  res.infer_useful_gflops = ac.forward_flops_used(obs.batch(), o.infer_agents) / res.infer_seconds * 1e-9;
}

// Training: forward + backward + Adam over the minibatch, with a PPO-like loss.
void bench_training(const NnBenchOptions& o, ActorCritic& ac, const ObsNormalizer& norm,
                    const ObsStore& train_obs, NnBenchResult& res) {
  const int nh = ac.heads().num_heads();
  const int train_rows = o.train_sequences * o.train_steps;
  std::vector<int32_t> actions(static_cast<size_t>(train_rows) * nh);
  std::vector<float> adv(train_rows), target(train_rows);
  InitRng rng(o.seed, 4);
  for (size_t i = 0; i < actions.size(); ++i)
    actions[i] = static_cast<int32_t>(rng.uniform() * ac.heads().sizes()[i % nh]);
  for (int i = 0; i < train_rows; ++i) {
    adv[i] = static_cast<float>(rng.normal());
    target[i] = static_cast<float>(rng.normal());
  }
  const CategoricalHeads& heads = ac.heads();
  const float inv_rows = 1.0f / static_cast<float>(train_rows);
  LossFn loss = [&](const ChunkOutputs& out, const ChunkGrads& g, std::span<double> stats) {
    float lp[kMaxLossRows], ent[kMaxLossRows], dlp[kMaxLossRows], dent[kMaxLossRows];
    // The heads' softmaxes from the loss to its gradient, as the PPO loss keeps them (per thread, sized
    // once).
    thread_local std::vector<double> saved;
    if (saved.size() < heads.saved_doubles(kMaxLossRows)) saved.resize(heads.saved_doubles(kMaxLossRows));
    for (int first = 0; first < out.rows; first += kMaxLossRows) {
      const int n = std::min(kMaxLossRows, out.rows - first);
      const int32_t* a = actions.data() + static_cast<ptrdiff_t>(out.first_row + first) * nh;
      const CMat logits = out.logits.block_rows(first, n);
      heads.log_prob_entropy(logits, a, lp, ent, saved.data());
      for (int i = 0; i < n; ++i) {
        const int row = out.first_row + first + i;
        dlp[i] = -adv[row] * inv_rows;
        dent[i] = -0.01f * inv_rows;
        const float diff = out.value[first + i] - target[row];
        g.d_value[first + i] = diff * inv_rows;
        stats[0] += -lp[i] * adv[row] - 0.01 * ent[i] + 0.5 * diff * diff;
      }
      heads.backward_saved(saved.data(), n, a, dlp, dent, g.d_logits.block_rows(first, n));
    }
  };
  AdamConfig acfg;
  acfg.max_grad_norm = 5.0f;
  acfg.weight_decay = 1e-6f;
  Adam adam(ac.params().layout(), acfg);
  std::vector<double> stats(1);
  res.train_seconds = median_seconds(o.min_seconds, [&] {
    ac.forward_backward(norm.view(), train_obs.batch(), o.train_sequences, o.train_steps, nullptr, nullptr,
                        loss, stats, ac.params().grads());
    adam.step(ac.params().values(), ac.params().grads());
  });
  res.train_flops_per_agent_step = 3.0 * ac.forward_flops(train_rows) / train_rows;
  res.train_agent_steps_per_s = train_rows / res.train_seconds;
  res.train_gflops = res.train_flops_per_agent_step * res.train_agent_steps_per_s * 1e-9;
  res.train_useful_gflops =
      3.0 * ac.forward_flops_used(train_obs.batch(), train_rows) / res.train_seconds * 1e-9;
}

// Eigen GEMM reference: one independent product per thread.
void bench_gemm(const NnBenchOptions& o, NnBenchResult& res) {
  const int m = 2560, k = 256, n = 1024;
  using RowMat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  std::vector<RowMat> a(o.threads), b(o.threads), c(o.threads);
  for (int t = 0; t < o.threads; ++t) {
    a[t] = RowMat::Random(m, k);
    b[t] = RowMat::Random(k, n);
    c[t] = RowMat::Zero(m, n);
  }
  const double seconds = median_seconds(
      o.min_seconds, [&] { tbb::parallel_for(0, o.threads, [&](int t) { c[t].noalias() = a[t] * b[t]; }); });
  res.gemm_gflops = 2.0 * m * k * n * o.threads / seconds * 1e-9;
}

// bf16 GEMM reference (precision bf16): the same shape and per-thread products on the bf16 kernel, its
// operands converted and packed once before the timing.
void bench_bf16_gemm(const NnBenchOptions& o, NnBenchResult& res) {
  const int m = 2560, k = 256, n = 1024;
  using RowMat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  std::vector<std::vector<bf16::bf16_t>> a(o.threads), b(o.threads);
  std::vector<std::vector<float>> c(o.threads);
  for (int t = 0; t < o.threads; ++t) {
    const RowMat af = RowMat::Random(m, k), bf = RowMat::Random(k, n);
    a[t].resize(bf16::a_elems(m, k));
    bf16::convert_a(af.data(), k, m, k, a[t].data());
    b[t].resize(bf16::packed_elems(k, n));
    bf16::pack_b(bf.data(), n, k, n, false, nullptr, b[t].data());
    c[t].assign(size_t(m) * n, 0.0f);
  }
  const double seconds = median_seconds(o.min_seconds, [&] {
    tbb::parallel_for(0, o.threads,
                      [&](int t) { bf16::gemm(a[t].data(), m, k, b[t].data(), n, c[t].data(), n, false); });
  });
  res.gemm_bf16_gflops = 2.0 * m * k * n * o.threads / seconds * 1e-9;
}

}  // namespace

NnBenchResult run_nn_bench(const NnBenchOptions& o) {
  if (o.threads < 1)
    throw std::invalid_argument("threads must be at least 1 (got " + std::to_string(o.threads) + ")");
  if (o.infer_agents < 1 || o.train_sequences < 1 || o.train_steps < 1)
    throw std::invalid_argument("benchmark batch sizes must be positive");
  NetConfig cfg = net_preset(o.model);
  cfg.obs = o.shape;
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(o.threads));

  ActorCritic ac(cfg, o.parallel);
  ac.set_precision(o.precision);
  ac.params().init(o.seed);
  NnBenchResult res;
  res.model = o.model;
  res.precision = std::string(precision_name(o.precision));
  res.precision_description = precision_description(o.precision);
  res.threads = o.threads;
  res.params = ac.num_params();
  res.masks = o.masks.name;

  // A normaliser fitted to the training data.
  const int train_rows = o.train_sequences * o.train_steps;
  const ObsStore train_obs = synthetic_obs(cfg.obs, o.masks, train_rows, o.seed + 1);
  ObsNormalizer norm(cfg.obs);
  norm.update(train_obs.self.data(), train_obs.lidar.data(), train_obs.agents.data(), train_obs.boxes.data(),
              train_obs.ramps.data(), nullptr, train_rows);

  bench_inference(o, ac, norm, res);
  bench_training(o, ac, norm, train_obs, res);
  bench_gemm(o, res);
  if (o.precision == Precision::kBf16) bench_bf16_gemm(o, res);
  return res;
}

}  // namespace hns::nn
