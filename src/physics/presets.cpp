#include <algorithm>

#include "physics/world.hpp"

namespace hns::physics {

// The presets of the scene registry's rows (batch::kScenes, batch/scenes.hpp): what each scene sets beyond
// the WorldConfig defaults.
WorldConfig WorldConfig::quadrant() {
  WorldConfig c;
  c.scene = SceneConfig::quadrant();
  c.horizon = 80;
  c.lock_ramps = false;
  return c;
}

WorldConfig WorldConfig::full() {
  WorldConfig c;
  c.scene = SceneConfig::full();
  c.horizon = 240;
  c.lock_ramps = true;
  const double open_arena[4] = {-6.0, -6.0, 12.0, 12.0};  // 18 x 18 m around the arena centre
  std::copy(std::begin(open_arena), std::end(open_arena), std::begin(c.restrict_rect));
  c.penalize_objects_out = false;
  return c;
}

WorldConfig WorldConfig::empty() {
  WorldConfig c;
  c.scene = SceneConfig::empty();
  c.horizon = 80;
  c.lock_ramps = true;
  return c;
}

WorldConfig WorldConfig::lockbox() {
  WorldConfig c;
  c.scene = SceneConfig::empty();
  c.scene.hiders = {1, 1};
  c.scene.seekers = {0, 0};
  c.scene.boxes = {1, 1};
  c.scene.elongated = {0, 0};
  c.scene.ramps = {0, 0};
  c.horizon = 60;
  c.prep_fraction = 0.0;
  c.lock_ramps = false;
  c.task = Task::kLockBox;
  return c;
}

namespace {
// docs/game.md §9: a lone hider (team 0) in the empty arena with the spoofed slots of a hide-and-seek policy
// (one other agent, one ramp at least), grab and lock as in the game, no preparation phase.
WorldConfig transfer_task(WorldConfig::Task task, int horizon) {
  WorldConfig c = WorldConfig::lockbox();
  c.task = task;
  c.horizon = horizon;
  c.obs_min_agents = 2;
  c.obs_min_ramps = 1;
  return c;
}
}  // namespace

WorldConfig WorldConfig::lock_and_return() {
  WorldConfig c = transfer_task(Task::kLockReturn, 120);
  c.scene.layout = Layout::kRandomWalls;
  c.scene.rooms = {6, 6};
  c.scene.prob_outside_walls = 1.0;
  c.scene.door_size = 2;
  return c;
}

WorldConfig WorldConfig::sequential_lock() {
  WorldConfig c = transfer_task(Task::kSequentialLock, 120);
  c.scene.layout = Layout::kVarTri;
  c.scene.boxes = {4, 4};
  c.scene.ramps = {3, 3};
  c.lock_ramps = true;
  return c;
}

WorldConfig WorldConfig::shelter() {
  WorldConfig c = transfer_task(Task::kShelter, 240);
  c.scene.boxes = {8, 8};
  c.scene.elongated = {3, 3};
  c.scene.target_diameter_min = 1.5;
  c.scene.target_diameter_max = 2.0;
  return c;
}

WorldConfig WorldConfig::blueprint() {
  WorldConfig c = transfer_task(Task::kBlueprint, 150);
  c.scene.boxes = {8, 8};
  c.scene.sites = {1, 4};
  return c;
}

WorldConfig WorldConfig::object_counting() {
  WorldConfig c = transfer_task(Task::kCounting, 80);
  c.scene.layout = Layout::kCounting;
  c.scene.boxes = {6, 6};
  return c;
}

WorldConfig WorldConfig::food_game() {
  WorldConfig c = full();
  c.scene.food = {5, 5};
  c.scene.food_middle = 0.25;
  c.scene.food_together_radius = 0.25;
  return c;  // FoodConfig's defaults are the full game's values (docs/game.md §5.4)
}

WorldConfig WorldConfig::dynamic_food_game() {
  WorldConfig c = full();
  c.scene.layout = Layout::kRandomWalls;
  c.scene.rooms = {1, 1};
  c.scene.prob_outside_walls = 0.0;  // no walls at all
  c.scene.hiders = {3, 3};
  c.scene.seekers = {2, 2};
  c.scene.boxes = {8, 8};
  c.scene.elongated = {8, 8};
  c.scene.ramps = {0, 0};
  c.obs_min_ramps = 1;  // the hide-and-seek policy's ramp slot, empty
  c.scene.food = {1, 1};
  c.scene.food_middle = 0.2;
  c.food.max_health = 1.0;
  c.food.respawn_steps = 1;
  c.food.relocate = true;
  return c;
}

}  // namespace hns::physics
