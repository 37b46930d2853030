// The rules of a game as one object: a Task is what a batch asks of the game it plays (docs/game.md §5, §9),
// one file per game in this folder. A batch plays the Task its config's rules name (GameRules::task,
// game.hpp), which the scene's preset sets (the scene registry, scenes.hpp).
//
//   hide_and_seek.cpp    the hide-and-seek game: quadrant, full, empty (its food variants: food.cpp)
//   food.cpp             the food variants' rules and presets: food, dynamic-food
//   lock_tasks.cpp       lockbox, lock-and-return, sequential-lock (docs/game.md §9.2)
//   shelter.cpp          shelter construction (§9.3)
//   blueprint.cpp        blueprint construction (§9.1)
//   object_counting.cpp  the object-counting probe (docs/transfer.md "Object counting")
//   task.cpp             what every task shares: the rules' and worlds' checks, the single-agent tasks'
//   reward
//
// Adding a game: one new file here (CMake builds every file of this folder) that defines the game's Task, a
// function returning it, and the preset of each of its scenes (a BatchConfig whose world and rules are set,
// rules.task pointing at the Task); then, in scenes.hpp, each preset's declaration and its row of kScenes
// (name, summary, family). The Task's validate() refuses the worlds its rules cannot play.
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
  // The world and rules this game cannot play: throws physics::ConfigError naming the first such field
  // (GameRules::validate calls it; the world's own fields are already valid). Task's: no construction sites
  // (blueprint's) and not the counting layout (object counting's), which only their games read.
  virtual void validate(const physics::WorldConfig& world, const GameRules& rules) const;
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

 protected:
  // The checks validate() overrides are made of (task.cpp; each throws physics::ConfigError).
  static void require_agent_zero(const physics::WorldConfig& world);      // hiders.min >= 1
  static void refuse_sites(const physics::WorldConfig& world);            // sites.max == 0
  static void refuse_counting_layout(const physics::WorldConfig& world);  // scene.layout != kCounting
  static void refuse_food(const physics::WorldConfig& world);             // food.max == 0
};

// A single-agent task of docs/game.md §9: agent 0 plays, every agent slot gets its reward, and hider_return
// sums agent 0's. What they all share is here once: an absorbed episode (task_complete: a completed
// blueprint) pays 0 from then on; otherwise an agent out of bounds gets -10 instead (§5.2); done at the
// horizon.
class SingleAgentTask : public Task {
 public:
  // Agent 0 exists, there is no food (a variant of hide-and-seek), and Task's checks.
  void validate(const physics::WorldConfig& world, const GameRules& rules) const override;
  void reward_and_done(EnvRef& env) const final;

 protected:
  // This step's reward of agent 0, written to every agent slot of `reward` (not called once absorbed).
  virtual void reward(EnvRef& env, float* reward) const = 0;
};

// docs/game.md §9: a lone hider (team 0) with one cube in the empty arena, no seeker, box or ramp else,
// `horizon` steps, no preparation phase, grab and lock as in the game (ramps not lockable), playing `task`
// (the lockbox scene, and what the other single-agent scenes start from).
BatchConfig lone_hider_scene(const Task& task, int horizon);
// The same with the spoofed slots of a hide-and-seek policy: one other agent and one ramp slot at least,
// empty and masked (docs/game.md §9 spoofed obs).
BatchConfig transfer_scene(const Task& task, int horizon);

// docs/game.md §5.2: an agent (or, in the quadrant game, a box or ramp) whose centre leaves the rules'
// restrict_rect.
inline constexpr float kOutOfBoundsReward = -10.0f;
inline bool out_of_bounds(const GameRules& rules, const float* p) {
  const double* rect = rules.restrict_rect;
  return p[0] < rect[0] || p[0] > rect[2] || p[1] < rect[1] || p[1] > rect[3];
}

}  // namespace hns::batch
