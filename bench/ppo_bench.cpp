// One whole PPO iteration (rollout of 8 quadrant envs x 80 steps, targets, 4 epochs x 4 minibatches of
// updates, normaliser update) per benchmark iteration, for the small and paper models, in fp32 and (where
// this CPU runs bf16 products: BM_PpoIterationBf16) in bf16. items/s is agent-steps/s end to end; counters
// give the share of time per phase.
#include <benchmark/benchmark.h>

#include <string>

#include "nn/bf16_gemm.hpp"

#include "ppo/trainer.hpp"

namespace {

void BM_PpoIteration(benchmark::State& state, const std::string& model, const std::string& precision) {
  hns::ppo::TrainConfig c;
  c.scene = "quadrant";
  c.model = model;
  c.precision = precision;
  c.envs = 8;
  c.threads = int(state.range(0));
  c.seed = 1;
  hns::ppo::Trainer trainer(c);
  trainer.iterate();  // warm-up: workspaces, normalisers
  int64_t steps = 0;
  double sim = 0, infer = 0, backward = 0, optimizer = 0, total = 0;
  for (auto _ : state) {
    const int64_t before = trainer.agent_steps();
    const hns::ppo::IterationMetrics m = trainer.iterate();
    steps += trainer.agent_steps() - before;
    sim += m.t_simulate;
    infer += m.t_infer;
    backward += m.t_backward;
    optimizer += m.t_optimizer;
    total += m.seconds;
  }
  state.SetItemsProcessed(steps);
  state.counters["simulate_share"] = sim / total;
  state.counters["infer_share"] = infer / total;
  state.counters["backward_share"] = backward / total;
  state.counters["optimizer_share"] = optimizer / total;
  state.counters["other_share"] = 1.0 - (sim + infer + backward + optimizer) / total;
}

void register_benchmarks() {
  for (const char* precision : {"fp32", "bf16"}) {
    const std::string p = precision;
    if (p == "bf16" && !hns::nn::bf16::available()) continue;
    const std::string suffix = p == "bf16" ? "Bf16" : "";
    for (const char* model : {"small", "paper"})
      benchmark::RegisterBenchmark(("BM_PpoIteration" + suffix + "/" + model).c_str(), BM_PpoIteration,
                                   std::string(model), p)
          ->ArgName("threads")
          ->Arg(1)
          ->Arg(2)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
  }
}

}  // namespace

int main(int argc, char** argv) {
  register_benchmarks();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
