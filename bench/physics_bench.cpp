// One world's env step with uniformly random actions, physics only (no observations): env-steps/s as
// items/s. Episodes reset (new scene) at the horizon, as in training.
#include <benchmark/benchmark.h>

#include <vector>

#include "physics/world.hpp"

namespace {

using hns::physics::AgentAction;
using hns::physics::Rng;
using hns::physics::World;
using hns::physics::WorldConfig;

void random_actions(Rng& rng, std::vector<AgentAction>& acts) {
  for (AgentAction& a : acts) {
    a = AgentAction{uint8_t(rng.uniform_int(0, 11)), uint8_t(rng.uniform_int(0, 11)),
                    uint8_t(rng.uniform_int(0, 11)), uint8_t(rng.uniform_int(0, 2)),
                    uint8_t(rng.uniform_int(0, 2))};
  }
}

// Physics only unless `visibility`: then the scalar vision reference runs after every step (grab and lock
// need it); without it grab and lock see nothing.
void run(benchmark::State& state, WorldConfig config, bool visibility = false) {
  config.compute_visibility = visibility;
  World world(config, 1, 0);
  world.reset(0);
  Rng rng(1, 0, 99);
  std::vector<AgentAction> acts(world.num_agents());
  int64_t bodies = 0;
  for (auto _ : state) {
    if (world.done()) {
      world.reset();
      acts.resize(world.num_agents());
    }
    random_actions(rng, acts);
    world.step(acts);
    bodies += world.num_agents() + world.num_objects();
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["bodies_per_step"] = double(bodies) / double(state.iterations());
  state.counters["substeps"] = config.physics.substeps;
}

// Quadrant game, 2 hiders v 2 seekers, 2 cubes, 1 ramp (docs/game.md §2.1).
void BM_WorldStepQuadrant(benchmark::State& state) {
  run(state, WorldConfig::quadrant());
}
BENCHMARK(BM_WorldStepQuadrant)->Unit(benchmark::kMicrosecond);

// Full game with 4 agents (2 v 2), 9 boxes and 2 ramps on random rooms.
WorldConfig full_2v2_9_boxes() {
  WorldConfig config = WorldConfig::full();
  config.scene.hiders = config.scene.seekers = {2, 2};
  config.scene.boxes = {9, 9};  // the full scene's elongated range, 3 to 9, fits
  config.scene.ramps = {2, 2};
  return config;
}
void BM_WorldStepFull(benchmark::State& state) {
  run(state, full_2v2_9_boxes());
}
BENCHMARK(BM_WorldStepFull)->Unit(benchmark::kMicrosecond);

// The same full scene with grab and lock live (scalar visibility after every step).
void BM_WorldStepFullWithVisibility(benchmark::State& state) {
  run(state, full_2v2_9_boxes(), true);
}
BENCHMARK(BM_WorldStepFullWithVisibility)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
