// The game settings of a batch that only the batch reads (the world's are physics::WorldConfig): which
// game's rules apply, the out-of-bounds rectangle and the food variants' eating rules. A scene of the
// registry (scenes.hpp) sets them beside its world.
#pragma once

#include "physics/world.hpp"

namespace hns::batch {

class Task;
// The hide-and-seek game's rules (tasks/hide_and_seek.cpp): the default game.
const Task& hide_and_seek_task();

// The food variants' eating rules (docs/game.md §5.4; the scene's food count, placement and clustering are in
// SceneConfig). Applied by the batch layer after each step: a hider eats 1 unit per step of every item with
// health left within eat_radius (3-D, from its centre) that it saw in the previous observation while no
// hider was seen, outside the preparation phase (seekers never eat); if the hiders at one item would eat
// more than it has, they share what is left. An item eaten up stays empty for respawn_steps steps, then its
// health resets (and, with relocate, it moves to a new spot of its placement region: dynamic food).
struct FoodConfig {
  double eat_radius = 0.5;    // m (the original's food_radius)
  double max_health = 40.0;   // units per item
  int respawn_steps = 5;      // 0 = an eaten-up item never comes back
  bool relocate = false;      // dynamic food
  bool joint_mean = true;     // each hider gets the hiders' mean of units eaten (false: its own, 'selfish')
  double reward_scale = 1.0;  // reward per unit
  bool eat_when_caught = false;  // true: hiders eat even while a hider is seen
};

// The rules a batch plays its worlds by. The defaults are the quadrant game's.
struct GameRules {
  // The game (tasks/task.hpp): the hide-and-seek game of docs/game.md §5 or one of the single-agent tasks of
  // docs/game.md §9. Its rewards, scripts and extra observations apply; it decides which worlds it can play.
  const Task* task = &hide_and_seek_task();
  // docs/game.md §5.2: an agent whose centre leaves this rectangle [x_min, y_min, x_max, y_max] (m) gets -10
  // that step; with penalize_objects_out, a box or ramp outside it costs every agent -10.
  double restrict_rect[4] = {0.1, 0.1, 5.9, 5.9};
  bool penalize_objects_out = true;
  // The food variants (the scene's food items; without any, nothing here applies).
  FoodConfig food;
  // Observation slots at least this many (0 = the world's maxima): a transfer task's lone agent sees a
  // hide-and-seek policy's entity types, the missing ones as slots with mask 0 (docs/game.md §9 spoofed obs).
  int obs_min_agents = 0;
  int obs_min_ramps = 0;
  // Throws physics::ConfigError naming the first bad field: the game's requirements on the world
  // (Task::validate), then the food settings and the rectangle.
  void validate(const physics::WorldConfig& world) const;
};

}  // namespace hns::batch
