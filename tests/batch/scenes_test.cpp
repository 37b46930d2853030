// The scene registry (src/batch/scenes.hpp): the one list of scenes, each row's preset and game, the lookups,
// and the count overrides.
#include "batch/scenes.hpp"

#include <gtest/gtest.h>

#include <map>
#include <set>
#include <string>

#include "batch/tasks/task.hpp"

namespace hns::batch {
namespace {

// Every row's name is unique and found by find_scene, its preset validates and is what scene_config
// returns, and its family agrees with the preset's game: the team game (with food exactly in the food
// family), a single-agent task (the transfer family, what hns eval accepts), or a scripted probe (what only
// hns counting runs).
TEST(SceneRegistry, EveryRowIsAValidPresetOfItsFamily) {
  std::set<std::string> names;
  for (const SceneInfo& s : kScenes) {
    SCOPED_TRACE(s.name);
    EXPECT_TRUE(names.insert(s.name).second);
    EXPECT_EQ(find_scene(s.name), &s);
    EXPECT_GT(std::string(s.summary).size(), 10u);
    const BatchConfig c = scene_config(s.name);
    EXPECT_NO_THROW(c.validate());
    EXPECT_EQ(s.preset().rules.task, c.rules.task);
    EXPECT_EQ(s.preset().world.scene.layout, c.world.scene.layout);
    const Task& task = *c.rules.task;
    const bool team_game = &task == &hide_and_seek_task();
    EXPECT_EQ(team_game, dynamic_cast<const SingleAgentTask*>(&task) == nullptr);
    EXPECT_EQ(s.family == SceneFamily::kHideAndSeek, team_game && c.world.scene.food.max == 0);
    EXPECT_EQ(s.family == SceneFamily::kFood, team_game && c.world.scene.food.max > 0);
    EXPECT_EQ(s.family == SceneFamily::kTransfer, !team_game && !task.scripted());
    EXPECT_EQ(s.family == SceneFamily::kProbe, task.scripted());
  }
  EXPECT_EQ(find_scene("moon"), nullptr);
  EXPECT_EQ(find_scene(""), nullptr);
  EXPECT_EQ(scene_names().size(), kScenes.size());
  EXPECT_EQ(scene_list(", ", SceneFamily::kTransfer),
            "lockbox, lock-and-return, sequential-lock, shelter, blueprint");
  try {
    (void)scene_config("moon");
    ADD_FAILURE() << "scene_config(\"moon\") did not throw";
  } catch (const physics::ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              "scene = 'moon' is invalid: must be one of quadrant, full, empty, lockbox, lock-and-return, "
              "sequential-lock, shelter, blueprint, object-counting, food, dynamic-food");
  }
}

// Each single-agent scene plays a task of its own (a row that names another row's task, say lockbox's rules
// in lock-and-return, is caught here); the hide-and-seek and food scenes all play the one team game.
TEST(SceneRegistry, EverySingleAgentScenePlaysATaskOfItsOwn) {
  std::map<const Task*, std::string> played_by;
  for (const SceneInfo& s : kScenes) {
    const Task* task = s.preset().rules.task;
    if (s.family == SceneFamily::kHideAndSeek || s.family == SceneFamily::kFood) {
      EXPECT_EQ(task, &hide_and_seek_task()) << s.name;
      continue;
    }
    const auto [it, fresh] = played_by.emplace(task, s.name);
    EXPECT_TRUE(fresh) << s.name << " plays the task of " << it->second;
  }
  EXPECT_EQ(played_by.size(), 6u);
}

// Fixed counts replace the preset's ranges; a fixed box count clamps the elongated range into it.
TEST(SceneRegistry, CountOverridesFixTheCounts) {
  BatchConfig c = scene_config("full");
  apply_overrides(c.world, CountOverrides{1, std::nullopt, 2, 0});
  const physics::SceneConfig& s = c.world.scene;
  EXPECT_EQ(s.hiders.min, 1);
  EXPECT_EQ(s.hiders.max, 1);
  EXPECT_EQ(s.seekers.max, scene_config("full").world.scene.seekers.max);
  EXPECT_EQ(s.boxes.min, 2);
  EXPECT_EQ(s.boxes.max, 2);
  EXPECT_EQ(s.elongated.min, 2);
  EXPECT_EQ(s.elongated.max, 2);
  EXPECT_EQ(s.ramps.max, 0);
}

}  // namespace
}  // namespace hns::batch
