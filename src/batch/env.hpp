// One env of a batch as the stages of a step see it, and the stages themselves. Internal to src/batch: the
// public interface is batch_sim.hpp.
//
// BatchSim (batch_sim.cpp) drives the step and owns the state; each stage is a free function of one env in a
// file of its own job:
//   layout.cpp        sizes of a batch, its state, its memory estimate
//   mirror.cpp        bodies read back from the world, the ray casts' shapes
//   perception.cpp    vision (cone + line of sight) and lidar
//   observations.cpp  the observation tensors
//   episode_stats.cpp the episode statistics (docs/game.md §7, docs/training.md "Stages")
//   tasks/            the games' rules, one file per game (tasks/task.hpp)
#pragma once

#include <cstdint>

#include "batch/batch_sim.hpp"
#include "physics/rng.hpp"

namespace hns::batch {

class Task;

// Env `index` of a batch: its config, sizes and state (the env's slice of every field), its world, the game
// it plays, and its random stream for the rules (dynamic food's new spots, drawn from (seed, env, episode)
// per episode).
struct EnvRef {
  const BatchConfig& config;
  const Layout& L;
  BatchState& s;
  physics::World& world;
  int index;
  const Task& task;
  physics::Rng& rng;
};

// Lines of sight one agent casts at most (other agents, boxes, ramps, food); the scene maxima keep far below.
inline constexpr int kMaxSightLines = 128;

// mirror.cpp: the env's bodies read back from its world into the SoA fields.
void mirror(EnvRef& env);
// mirror.cpp: the ray casts' shapes of the moving bodies (boxes, ramps, agents and their arms) from the
// mirror; the static ones (walls, the shelter's cylinder) once per episode.
void build_shapes(EnvRef& env);
void build_static_shapes(EnvRef& env);
// mirror.cpp: env `env`'s occluders as the ray kernel sees them.
ShapesView shapes_view(const Layout& L, const BatchState& s, const physics::World& world, int env);
inline ShapesView shapes_view(const EnvRef& env) {
  return shapes_view(env.L, env.s, env.world, env.index);
}

// perception.cpp: docs/game.md §4.1 vision (vis_* and the world's object visibility), §4.2 lidar.
void vision(EnvRef& env);
void lidar(EnvRef& env);

// observations.cpp: the observation tensors and masks of every agent (docs/game.md §4.3-§4.6, §14.1), the
// task's own rows included.
void observe(EnvRef& env);

// episode_stats.cpp: the PrepStat slots from the mirror (at the end of prep into stat_prep, and at the
// episode's end); the seeking phase's RunStat slots, updated every step after vision; the record of a
// finished episode.
void measure_stats(const EnvRef& env, float out[kNumPrepStats]);
void track_seeking(EnvRef& env, bool any_seen);
void record_episode(const EnvRef& env, bool discarded, EpisodeStats& out);

// tasks/shelter.cpp: docs/game.md §9.3's rays from the arena's edges that reach env `env`'s cylinder now.
int shelter_rays_reaching(const Layout& L, const BatchState& s, const physics::World& world, int env);

}  // namespace hns::batch
