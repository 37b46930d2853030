// One whole PPO iteration (rollout of 8 quadrant envs x 80 steps, targets, 4 epochs x 4 minibatches of
// updates, normaliser update) per benchmark iteration, for the small and paper models. items/s is
// agent-steps/s end to end; counters give the share of time per phase.
#include <benchmark/benchmark.h>

#include <string>

#include "ppo/trainer.hpp"

namespace {

void BM_PpoIteration(benchmark::State& state, const std::string& model) {
  hns::ppo::TrainConfig c;
  c.scene = "quadrant";
  c.model = model;
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

BENCHMARK_CAPTURE(BM_PpoIteration, small, std::string("small"))
    ->ArgName("threads")
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_PpoIteration, paper, std::string("paper"))
    ->ArgName("threads")
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
