// The batch simulator: the ray fan kernel behind vision and lidar (rays/s, SIMD vs scalar); vision, lidar and
// observation packing over a batch (agent-steps/s); the whole batch step (env-steps/s at 1 and 2 threads)
// with its per-phase rates.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "batch/batch_sim.hpp"
#include "batch/ray_kernels.hpp"
#include "batch/scenes.hpp"

namespace {

using hns::batch::AgentAction;
using hns::batch::BatchConfig;
using hns::batch::BatchSim;
using hns::physics::Rng;

// A full scene (2 v 2, 9 boxes, 2 ramps) after a few random steps, its shapes ready for ray casts.
struct FullScene {
  BatchSim sim;
  FullScene() : sim(make_config()) {
    std::vector<AgentAction> acts(size_t(sim.layout().max_agents), AgentAction{10, 5, 7, 0, 0});
    for (int k = 0; k < 5; ++k) sim.step(acts);
  }
  static BatchConfig make_config() {
    BatchConfig c;
    c.world = hns::physics::WorldConfig::full();
    hns::batch::apply_overrides(c.world, hns::batch::CountOverrides{2, 2, 9, 2});
    c.num_envs = 1;
    return c;
  }
  hns::batch::ShapesView shapes() const { return sim.shapes(0); }
};

// Uniformly random movement bins, grab and lock bits for every action slot.
void random_actions(Rng& rng, std::vector<AgentAction>& acts) {
  for (AgentAction& a : acts) {
    a = AgentAction{uint8_t(rng.uniform_int(0, 11)), uint8_t(rng.uniform_int(0, 11)),
                    uint8_t(rng.uniform_int(0, 11)), uint8_t(rng.uniform_int(0, 2)),
                    uint8_t(rng.uniform_int(0, 2))};
  }
}

// Every agent's 30-ray lidar fan (6 m, horizontal, its own body skipped), as the batch casts them; rays/s
// as items/s.
template <void (*Cast)(const hns::batch::ShapesView&, const hns::batch::RayFan&, float*, int32_t*)>
void BM_RayFan(benchmark::State& state) {
  FullScene scene;
  const hns::batch::ShapesView shapes = scene.shapes();
  const float* p = scene.sim.state().agent_pos.data();
  float dx[30], dy[30], dz[30], len[30], t[30];
  int32_t id[30];
  for (int k = 0; k < 30; ++k) {
    const double a = 2 * 3.14159265358979 * k / 30;
    dx[k] = float(std::cos(a)), dy[k] = float(std::sin(a)), dz[k] = 0.0f, len[k] = 6.0f;
  }
  const int agents = shapes.live_spheres / shapes.spheres_per_body;
  for (auto _ : state) {
    for (int a = 0; a < agents; ++a) {
      Cast(shapes,
           hns::batch::RayFan{p[3 * a], p[3 * a + 1], p[3 * a + 2], dx, dy, dz, len, 30, shapes.sphere_id(a)},
           t, id);
      benchmark::DoNotOptimize(t);
      benchmark::DoNotOptimize(id);
    }
  }
  state.SetItemsProcessed(state.iterations() * int64_t(agents) * 30);
  state.counters["shapes"] = shapes.live_boxes + shapes.live_wedges + shapes.live_spheres;
}
BENCHMARK(BM_RayFan<hns::batch::first_hits>)->Name("BM_RayFan/simd");
BENCHMARK(BM_RayFan<hns::batch::first_hits_scalar>)->Name("BM_RayFan/scalar");

// One kernel over a batch of 64 full-scene envs (paper counts, drawn per episode) after 30 random steps:
// every env's vision, lidar or observation packing recomputed from the SoA mirror as step() runs it.
// items/s = agent-steps/s (one agent's vision, lidar fan or observations).
void per_env_kernel(benchmark::State& state, void (BatchSim::*kernel)(int)) {
  BatchConfig config;
  config.world = hns::physics::WorldConfig::full();
  config.num_envs = 64;
  BatchSim sim(config);
  std::vector<AgentAction> acts(size_t(config.num_envs) * sim.layout().max_agents);
  Rng rng(4, 5, 6);
  for (int k = 0; k < 30; ++k) {
    random_actions(rng, acts);
    sim.step(acts);
  }
  int64_t agents = 0;
  for (int e = 0; e < config.num_envs; ++e) agents += sim.world(e).num_agents();
  for (auto _ : state) {
    for (int e = 0; e < config.num_envs; ++e) (sim.*kernel)(e);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * agents);
  state.counters["agents_per_env"] = double(agents) / config.num_envs;
}
void BM_Vision(benchmark::State& state) {
  per_env_kernel(state, &BatchSim::compute_vision);
}
void BM_Lidar(benchmark::State& state) {
  per_env_kernel(state, &BatchSim::compute_lidar);
}
void BM_ObservationPacking(benchmark::State& state) {
  per_env_kernel(state, &BatchSim::compute_observations);
}
BENCHMARK(BM_Vision);
BENCHMARK(BM_Lidar);
BENCHMARK(BM_ObservationPacking);

// Whole batch step of 64 envs with random actions; items/s = env-steps/s. Counters give each phase's rate
// in env-steps per second of thread time (physics, mirror, vision+lidar, observation packing) and its share
// of the step's thread time (`*_share`, which tools/perf-gate shows for a flagged benchmark).
void batch_step(benchmark::State& state, const char* scene) {
  BatchConfig config = hns::batch::scene_config(scene);
  config.num_envs = 64;
  config.threads = int(state.range(0));
  BatchSim sim(config);
  std::vector<AgentAction> acts(size_t(config.num_envs) * sim.layout().max_agents);
  Rng rng(1, 2, 3);
  sim.reset_timers();
  for (auto _ : state) {
    state.PauseTiming();
    random_actions(rng, acts);
    state.ResumeTiming();
    sim.step(acts);
  }
  const double env_steps = double(state.iterations()) * config.num_envs;
  state.SetItemsProcessed(int64_t(env_steps));
  const hns::batch::PhaseTimes& ph = sim.phase_times();
  state.counters["physics_env_steps_per_s"] = env_steps / ph.physics;
  state.counters["mirror_env_steps_per_s"] = env_steps / ph.mirror;
  state.counters["vision_lidar_env_steps_per_s"] = env_steps / ph.perception;
  state.counters["observations_env_steps_per_s"] = env_steps / ph.observations;
  const double total = ph.total();
  state.counters["physics_share"] = ph.physics / total;
  state.counters["mirror_share"] = ph.mirror / total;
  state.counters["vision_lidar_share"] = ph.perception / total;
  state.counters["observations_share"] = ph.observations / total;
  state.counters["rewards_share"] = ph.rewards / total;
}
void BM_BatchStepQuadrant(benchmark::State& state) {
  batch_step(state, "quadrant");
}
void BM_BatchStepFull(benchmark::State& state) {
  batch_step(state, "full");
}
BENCHMARK(BM_BatchStepQuadrant)
    ->Arg(1)
    ->Arg(2)
    ->ArgName("threads")
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_BatchStepFull)->Arg(1)->Arg(2)->ArgName("threads")->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
