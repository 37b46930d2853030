// The rules of a game as one object: a Task is what a batch asks of the game it plays (docs/game.md §5, §9),
// one file per game in this folder, chosen once per batch from the world config's task (the scene registry
// batch::kScenes names a preset, the preset its WorldConfig::Task, task_for() the Task).
//
//   hide_and_seek.cpp    the hide-and-seek game: quadrant, full, empty, and the food variants (with food.cpp)
//   lock_tasks.cpp       lockbox, lock-and-return, sequential-lock (docs/game.md §9.2)
//   shelter.cpp          shelter construction (§9.3)
//   blueprint.cpp        blueprint construction (§9.1)
//   object_counting.cpp  the object-counting probe (docs/transfer.md "Object counting")
//   task.cpp             what every single-agent task shares; registry.cpp: which task plays which game
//
// Hooks, in the order one env's step calls them (batch_sim.hpp has the whole step):
//   episode start:  World::reset -> start_episode -> mirror, shapes, vision, lidar -> episode_started
//   each step:      [scripted(): idle actions] World::step -> after_physics -> mirror, shapes, vision, lidar
//                   -> reward_and_done -> (episode over: statistics, reset) -> observations, then observe
// A task keeps no state of its own: what an env remembers between steps is in its BatchState fields
// (task_target, task_complete, food_health, ...), so that every field stays visible, copyable and checked.
#pragma once

#include <cstdint>

#include "batch/env.hpp"

namespace hns::batch {

class Task {
 public:
  virtual ~Task() = default;
  // The "hider" self feature of every agent: -1 = its team (1 for hiders), 0 or 1 = that constant (the
  // single-agent tasks that spoof a hide-and-seek policy's observation, docs/game.md §9).
  virtual int hider_observation() const { return -1; }
  // True: the agents' actions are ignored; the world steps with idle actions and after_physics poses it.
  virtual bool scripted() const { return false; }
  // Episode start, after the world's reset and before the first mirror: the task's state fields that the
  // first vision reads, the script's first poses.
  virtual void start_episode(EnvRef& /*env*/, uint64_t /*episode*/) const {}
  // Episode start, after the first mirror, vision and lidar (targets measured from the spawn).
  virtual void episode_started(EnvRef& /*env*/) const {}
  // After each step's physics, before the mirror.
  virtual void after_physics(EnvRef& /*env*/) const {}
  // After each step's vision and lidar: every agent slot's reward (padding slots 0), the episode's returns,
  // the statistics the game keeps per step, and done. No default: a game without rules does not compile.
  virtual void reward_and_done(EnvRef& env) const = 0;
  // The game's own observation rows, after the common ones (the fourth entity type: sites, food).
  virtual void observe(EnvRef& /*env*/) const {}
};

// A single-agent task of docs/game.md §9: agent 0 plays, every agent slot gets its reward, and hider_return
// sums agent 0's. What they all share is here once: an absorbed episode (task_complete: a completed
// blueprint) pays 0 from then on; otherwise an agent out of bounds gets -10 instead (§5.2); done at the
// horizon.
class SingleAgentTask : public Task {
 public:
  void reward_and_done(EnvRef& env) const final;

 protected:
  // This step's reward of agent 0, written to every agent slot of `reward` (not called once absorbed).
  virtual void reward(EnvRef& env, float* reward) const = 0;
};

// The task that plays a world config's game (registry.cpp). Throws std::logic_error for a WorldConfig::Task
// value without one.
const Task& task_for(physics::WorldConfig::Task task);

// docs/game.md §5.2: an agent (or, in the quadrant game, a box or ramp) whose centre leaves the config's
// restrict_rect.
inline constexpr float kOutOfBoundsReward = -10.0f;
inline bool out_of_bounds(const physics::WorldConfig& config, const float* p) {
  const double* rect = config.restrict_rect;
  return p[0] < rect[0] || p[0] > rect[2] || p[1] < rect[1] || p[1] > rect[3];
}

}  // namespace hns::batch
