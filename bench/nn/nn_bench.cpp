// Policy + value network throughput for both presets, next to a plain Eigen GEMM of the LSTM's shape in the
// same run (the machine's peak reference); where the CPU has AVX512-BF16 also the bf16 forms, the bf16 GEMM
// reference and (with the vdpbf16ps kernel) one attention head's bf16 scores. Agent-steps/s are reported as
// items/s, achieved GFLOP/s as a counter (FLOP counting as in nn/nn_bench.hpp). Arguments: preset (0 = paper,
// 1 = small), TBB threads.
//   build-nn/bench/nn/bench_nn --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include "nn/nn_bench.hpp"
#include "nn/actor_critic.hpp"
#include "nn/adam.hpp"
#include "nn/bf16_gemm.hpp"
#include "nn/obs_store.hpp"

#include <benchmark/benchmark.h>
#include <oneapi/tbb/global_control.h>
#include <oneapi/tbb/parallel_for.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

namespace hns::nn {
namespace {

// Random observations shaped like the `full` scene, all entities present, about 60 % seen (hns bench --nn's
// synthetic observations, nn/nn_bench.hpp, without its absent last box).
ObsStore random_obs(const ObsShape& s, int rows) {
  MaskDensity d;
  d.alternate_last_box = false;
  return synthetic_obs(s, d, rows, 7);
}

void set_counters(benchmark::State& state, double agent_steps, double flops) {
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * agent_steps));
  state.counters["GFLOP/s"] = benchmark::Counter(flops * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
}

// One inference step (policy + value forward, sampling) for 1024 agents.
void BM_NnInfer(benchmark::State& state, const char* preset, Precision precision) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, state.range(0));
  const NetConfig cfg = net_preset(preset);
  ActorCritic ac(cfg);
  ac.params().init(1);
  ac.set_precision(precision);
  const int agents = 1024;
  const ObsStore obs = random_obs(cfg.obs, agents);
  const ObsNormalizer norm(cfg.obs);
  std::vector<float> ps(static_cast<size_t>(agents) * ac.state_width()), vs(ps.size());
  std::vector<float> uniforms(static_cast<size_t>(agents) * ac.heads().num_heads(), 0.5f);
  std::vector<int32_t> actions(uniforms.size());
  std::vector<float> logp(agents), value(agents);
  for (auto _ : state)
    ac.act(norm.view(), obs.batch(), agents, ps.data(), vs.data(), uniforms.data(),
           {actions.data(), logp.data(), value.data(), nullptr});
  set_counters(state, agents, ac.forward_flops(agents));
}

// Forward + backward + Adam over a minibatch of 256 BPTT chunks of 10 steps.
void BM_NnTrain(benchmark::State& state, const char* preset, Precision precision) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, state.range(0));
  const NetConfig cfg = net_preset(preset);
  ActorCritic ac(cfg);
  ac.params().init(1);
  ac.set_precision(precision);
  const int seqs = 256, steps = 10, rows = seqs * steps;
  const ObsStore obs = random_obs(cfg.obs, rows);
  const ObsNormalizer norm(cfg.obs);
  const int nl = ac.heads().num_logits();
  // A fixed linear loss: the backward pass costs the same whatever the loss.
  const LossFn loss = [nl](const ChunkOutputs& out, const ChunkGrads& g, std::span<double>) {
    for (int r = 0; r < out.rows; ++r) {
      for (int k = 0; k < nl; ++k) g.d_logits.at(r, k) = 1e-4f * static_cast<float>(k % 3 - 1);
      g.d_value[r] = 1e-4f;
    }
  };
  Adam adam(ac.params().layout(), {});
  std::vector<double> stats;
  double learn = 0, optimizer = 0;  // seconds in forward + backward and in Adam (the perf gate's split)
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    ac.forward_backward(norm.view(), obs.batch(), seqs, steps, nullptr, nullptr, loss, stats,
                        ac.params().grads());
    const auto t1 = std::chrono::steady_clock::now();
    adam.step(ac.params().values(), ac.params().grads());
    learn += std::chrono::duration<double>(t1 - t0).count();
    optimizer += std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  }
  set_counters(state, rows, 3.0 * ac.forward_flops(rows));
  state.counters["forward_backward_share"] = learn / (learn + optimizer);
  state.counters["optimizer_share"] = optimizer / (learn + optimizer);
}

// Eigen float GEMM of the LSTM input product's training shape, one independent product per thread.
void BM_EigenGemm(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  using RowMat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const int m = 2560, k = 256, n = 1024;
  std::vector<RowMat> a(threads), b(threads), c(threads);
  for (int t = 0; t < threads; ++t) {
    a[t] = RowMat::Random(m, k);
    b[t] = RowMat::Random(k, n);
    c[t] = RowMat::Zero(m, n);
  }
  for (auto _ : state) {
    tbb::parallel_for(0, threads, [&](int t) { c[t].noalias() = a[t] * b[t]; });
    benchmark::DoNotOptimize(c[0].data());
  }
  state.counters["GFLOP/s"] =
      benchmark::Counter(2.0 * m * k * n * threads * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
}

// The bf16 reference: the same shape through the bf16 kernel (operands converted and packed once, outside
// the timed loop), one independent product per thread.
void BM_Bf16Gemm(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  const int m = 2560, k = 256, n = 1024;
  std::vector<std::vector<bf16::bf16_t>> a(threads), b(threads);
  std::vector<std::vector<float>> c(threads);
  const std::vector<float> x(static_cast<size_t>(m) * k, 0.5f), w(static_cast<size_t>(k) * n, 0.25f);
  for (int t = 0; t < threads; ++t) {
    a[t].resize(bf16::a_elems(m, k));
    b[t].resize(bf16::packed_elems(k, n));
    c[t].resize(static_cast<size_t>(m) * n);
    bf16::convert_a(x.data(), k, m, k, a[t].data());
    bf16::pack_b(w.data(), n, k, n, false, nullptr, b[t].data());
  }
  for (auto _ : state) {
    tbb::parallel_for(0, threads,
                      [&](int t) { bf16::gemm(a[t].data(), m, k, b[t].data(), n, c[t].data(), n, false); });
    benchmark::DoNotOptimize(c[0].data());
  }
  state.counters["GFLOP/s"] =
      benchmark::Counter(2.0 * m * k * n * threads * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
}

// The bf16 attention scores of one head of 32 features (both models' heads) for `keys` entities: the q·k
// products of nn/attention.cpp's forward pass, queries and keys read from the rows of a q/k projection of
// the `small` model (128 floats: q of both heads, then k). Up to 16 keys take the kernel's path that keeps
// the keys in registers, more the general one. Items: scores.
void BM_Bf16AttentionScores(benchmark::State& state) {
  const int keys = static_cast<int>(state.range(0)), dh = 32, row = 128;
  std::vector<float> qk(static_cast<size_t>(keys) * row);
  for (size_t i = 0; i < qk.size(); ++i) qk[i] = static_cast<float>(i % 17) * 0.125f - 1.0f;
  std::vector<float> scores(static_cast<size_t>(keys) * keys);
  std::vector<bf16::bf16_t> scratch(bf16::attention_scratch_elems(keys, dh));
  for (auto _ : state) {
    bf16::attention_scores(qk.data(), row, qk.data() + row / 2, row, keys, dh, scores.data(), keys,
                           scratch.data());
    benchmark::DoNotOptimize(scores.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * keys * keys);
}

void register_benchmarks() {
  auto threads = [](benchmark::internal::Benchmark* b) {
    b->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
  };
  // BM_NnInfer/paper, ... (fp32) or BM_NnInferBf16/paper, ...
  auto networks = [&](const std::string& suffix, Precision precision) {
    for (const char* preset : {"paper", "small"}) {
      threads(benchmark::RegisterBenchmark(("BM_NnInfer" + suffix + "/" + preset).c_str(), BM_NnInfer, preset,
                                           precision));
      threads(benchmark::RegisterBenchmark(("BM_NnTrain" + suffix + "/" + preset).c_str(), BM_NnTrain, preset,
                                           precision));
    }
  };
  threads(benchmark::RegisterBenchmark("BM_EigenGemm", BM_EigenGemm));
  networks("", Precision::kFp32);
  // The bf16 products only where this CPU runs them (tools/perf-gate adds them to its suites there).
  if (!bf16::available()) return;
  threads(benchmark::RegisterBenchmark("BM_Bf16Gemm", BM_Bf16Gemm));
  networks("Bf16", Precision::kBf16);
  // The scores are a vdpbf16ps kernel of their own (the AMX kernels keep float scores).
  if (bf16::kernel() == bf16::Kernel::kAvx512Bf16)
    benchmark::RegisterBenchmark("BM_Bf16AttentionScores", BM_Bf16AttentionScores)
        ->ArgName("keys")
        ->Arg(2)
        ->Arg(4)
        ->Arg(7)
        ->Arg(16)
        ->Arg(17)
        ->Unit(benchmark::kNanosecond);
}

}  // namespace
}  // namespace hns::nn

int main(int argc, char** argv) {
  hns::nn::register_benchmarks();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
