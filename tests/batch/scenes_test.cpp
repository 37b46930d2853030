// The scene registry (src/batch/scenes.hpp): the one list of scenes, its lookups, and the count overrides.
#include "batch/scenes.hpp"

#include <gtest/gtest.h>

#include <set>
#include <string>

namespace hns::batch {
namespace {

// Every row's name is unique and found by find_scene, its preset validates and is what scene_config
// returns, and its family agrees with the preset's task (the transfer family is what hns eval accepts, the
// probe what only hns counting runs).
TEST(SceneRegistry, EveryRowIsAValidPresetOfItsFamily) {
  std::set<std::string> names;
  for (const SceneInfo& s : kScenes) {
    SCOPED_TRACE(s.name);
    EXPECT_TRUE(names.insert(s.name).second);
    EXPECT_EQ(find_scene(s.name), &s);
    EXPECT_GT(std::string(s.summary).size(), 10u);
    const BatchConfig c = scene_config(s.name);
    EXPECT_NO_THROW(c.validate());
    const physics::WorldConfig& w = c.world;
    EXPECT_EQ(s.preset().task, w.task);
    EXPECT_EQ(s.preset().scene.layout, w.scene.layout);
    const bool probe = w.task == physics::WorldConfig::Task::kCounting;
    EXPECT_EQ(s.family == SceneFamily::kProbe, probe);
    EXPECT_EQ(s.family == SceneFamily::kTransfer, w.is_transfer_task() && !probe);
    EXPECT_EQ(s.family == SceneFamily::kFood,
              w.task == physics::WorldConfig::Task::kHideAndSeek && w.scene.food.max > 0);
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
