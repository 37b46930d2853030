// The rules a batch plays by (batch/game.hpp, tasks/task.hpp): a game or a single-agent task without a reward
// cannot exist (there is no default reward: a new task that forgot its rules once silently got shelter's);
// each game refuses the worlds its rules cannot play and the rules' own bad fields, with the messages that
// name the field; the spoofed hider bit of the single-agent tasks.
#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <type_traits>
#include <vector>

#include "batch/scenes.hpp"
#include "batch/tasks/task.hpp"

namespace hns::batch {
namespace {

// A game and a single-agent task that leave out their reward are abstract: no object of either can be made,
// so a scene cannot name one.
struct GameWithoutReward : Task {
  void observe(EnvRef& /*env*/) const override {}
};
struct TaskWithoutReward : SingleAgentTask {
  void start_episode(EnvRef& /*env*/, uint64_t /*episode*/) const override {}
};
static_assert(std::is_abstract_v<GameWithoutReward>);
static_assert(std::is_abstract_v<TaskWithoutReward>);
static_assert(std::is_abstract_v<Task> && std::is_abstract_v<SingleAgentTask>);

// docs/game.md §4.3, §9: shelter, blueprint and object counting observe a constant 0 as the hider bit; the
// other games the agent's team.
TEST(GameRules, TheSpoofingTasksObserveAConstantHiderBit) {
  for (const SceneInfo& scene : kScenes) {
    const std::string n = scene.name;
    const bool constant = n == "shelter" || n == "blueprint" || n == "object-counting";
    EXPECT_EQ(scene.preset().rules.task->hider_observation(), constant ? 0 : -1) << n;
  }
}

struct Refusal {
  const char* scene;
  std::function<void(BatchConfig&)> change;
  std::string message;  // what BatchConfig::validate says
};

// One change per rule to a scene that is valid without it; the message names the field as the rules'
// fields and the games' requirements always have.
TEST(GameRules, EachGameRefusesTheWorldsItCannotPlay) {
  const std::vector<Refusal> refusals = {
      {"lockbox",
       [](BatchConfig& c) {
         c.world.scene.hiders = {0, 1};
         c.world.scene.seekers = {1, 1};  // (a world with no agent at all is refused before the game sees it)
       },
       "hiders.min = 0 is invalid: must be >= 1 in a transfer task (agent 0 does the task)"},
      {"shelter",
       [](BatchConfig& c) { c.world.scene.target_diameter_min = c.world.scene.target_diameter_max = 0; },
       "target_diameter_max = 0 is invalid: must be > 0 in the shelter task (its cylinder)"},
      {"blueprint",
       [](BatchConfig& c) {
         c.world.scene.sites = {0, 4};
       },
       "sites.min = 0 is invalid: must be >= 1 in the blueprint task (its construction sites)"},
      {"blueprint",
       [](BatchConfig& c) {
         c.world.scene.boxes = c.world.scene.elongated = {0, 0};
       },
       "boxes.min = 0 is invalid: must be >= 1 in the blueprint task (its building blocks)"},
      {"lockbox",
       [](BatchConfig& c) {
         c.world.scene.sites = {1, 1};
       },
       "sites.max = 1 is invalid: must be 0 outside the blueprint task (construction sites are its rules')"},
      {"empty",
       [](BatchConfig& c) {
         c.world.scene.sites = {1, 1};
       },
       "sites.max = 1 is invalid: must be 0 outside the blueprint task (construction sites are its rules')"},
      {"lockbox", [](BatchConfig& c) { c.world.scene.layout = physics::Layout::kCounting; },
       "scene.layout = 4 is invalid: the counting layout goes with the object-counting task, and only with "
       "it"},
      {"object-counting", [](BatchConfig& c) { c.world.scene.layout = physics::Layout::kEmpty; },
       "scene.layout = 0 is invalid: the counting layout goes with the object-counting task, and only with "
       "it"},
      {"lockbox",
       [](BatchConfig& c) {
         c.world.scene.food = {1, 1};
       },
       "food.max = 1 is invalid: must be 0 in a transfer task (food is a variant of hide-and-seek)"},
      {"sequential-lock", [](BatchConfig& c) { c.world.lock_in_order = false; },
       "lock_in_order = 0 is invalid: must be 1 in the sequential-lock task (its boxes are locked in order)"},
      {"lockbox", [](BatchConfig& c) { c.world.lock_in_order = true; },
       "lock_in_order = 1 is invalid: must be 0 in the lockbox and lock-and-return tasks (any box may be "
       "locked)"},
      {"lockbox", [](BatchConfig& c) { c.rules.obs_min_agents = 33; },
       "obs_min_agents = 33 is invalid: must be in [0, 32]"},
      {"quadrant", [](BatchConfig& c) { c.rules.obs_min_ramps = -1; },
       "obs_min_ramps = -1 is invalid: must be in [0, 16]"},
      {"food", [](BatchConfig& c) { c.rules.food.eat_radius = 0; },
       "food.eat_radius = 0 is invalid: must be in (0, 10] m"},
      {"food", [](BatchConfig& c) { c.rules.food.max_health = 1000001; },
       "food.max_health = 1000001 is invalid: must be in (0, 1000000] units"},
      {"food", [](BatchConfig& c) { c.rules.food.respawn_steps = -1; },
       "food.respawn_steps = -1 is invalid: must be in [0, 1000000] (0: never)"},
      {"food", [](BatchConfig& c) { c.rules.food.reward_scale = 1e4; },
       "food.reward_scale = 10000 is invalid: must be in [-1000, 1000]"},
      {"quadrant", [](BatchConfig& c) { c.rules.restrict_rect[0] = 6.5; },
       "restrict_rect x_min = 6.5 is invalid: must be < x_max"},
      {"full", [](BatchConfig& c) { c.rules.restrict_rect[3] = -6.0; },
       "restrict_rect y_min = -6 is invalid: must be < y_max"},
      {"quadrant", [](BatchConfig& c) { c.rules.task = nullptr; },
       "task is invalid: the rules name no game (GameRules::task)"},
  };
  for (const Refusal& r : refusals) {
    BatchConfig c = scene_config(r.scene);
    ASSERT_NO_THROW(c.validate()) << r.scene;
    r.change(c);
    try {
      c.validate();
      ADD_FAILURE() << r.scene << ": accepted, expected " << r.message;
    } catch (const physics::ConfigError& e) {
      EXPECT_EQ(std::string(e.what()), r.message) << r.scene;
    }
  }
}

}  // namespace
}  // namespace hns::batch
