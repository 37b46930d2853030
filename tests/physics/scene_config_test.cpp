// SceneConfig::validate (docs/game.md §2.6): every bad field names itself, the message gives the value and
// what is allowed, impossible counts are refused and wide but possible ranges accepted.
#include "physics/scene.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "scene_test_util.hpp"

namespace hns::physics {
namespace {

using namespace scene_test;

// ---------------------------------------------------------------------------------------------------------------
// validate(): every bad field names itself.
struct BadField {
  const char* field;
  void (*breaks)(SceneConfig&);
};

TEST(SceneConfigValidate, EachBadFieldIsNamed) {
  const BadField cases[] = {
      {"hiders.min", [](SceneConfig& c) { c.hiders.min = -1; }},
      {"seekers.max",
       [](SceneConfig& c) {
         c.seekers = {2, 1};
       }},
      {"boxes.min", [](SceneConfig& c) { c.boxes.min = -2; }},
      {"boxes.max",
       [](SceneConfig& c) {
         c.boxes = {3, 2};
       }},
      {"boxes.max",
       [](SceneConfig& c) {
         c.boxes = {0, 33};
       }},
      {"elongated.max",
       [](SceneConfig& c) {
         c.elongated = {2, 1};
       }},
      {"elongated.min",
       [](SceneConfig& c) {
         c.elongated = {5, 5};
       }},
      {"ramps.max",
       [](SceneConfig& c) {
         c.ramps = {0, 17};
       }},
      {"ramps.min", [](SceneConfig& c) { c.ramps.min = -1; }},
      {"hiders.min + seekers.min",
       [](SceneConfig& c) {
         c.hiders = {0, 2}, c.seekers = {0, 2};
       }},
      {"hiders.max + seekers.max",
       [](SceneConfig& c) {
         c.hiders = {2, 20}, c.seekers = {2, 13};
       }},
      {"door_size", [](SceneConfig& c) { c.door_size = 0; }},
      {"door_size", [](SceneConfig& c) { c.door_size = 11; }},
      {"p_door_dropout", [](SceneConfig& c) { c.p_door_dropout = -0.1; }},
      {"p_door_dropout", [](SceneConfig& c) { c.p_door_dropout = std::numeric_limits<double>::quiet_NaN(); }},
      {"prob_outside_walls", [](SceneConfig& c) { c.prob_outside_walls = 1.5; }},
      {"together_radius", [](SceneConfig& c) { c.together_radius = -0.5; }},
      {"together_radius",
       [](SceneConfig& c) { c.together_radius = std::numeric_limits<double>::infinity(); }},
      {"max_tries_per_object", [](SceneConfig& c) { c.max_tries_per_object = 0; }},
      {"max_regenerations", [](SceneConfig& c) { c.max_regenerations = 0; }},
      {"layout", [](SceneConfig& c) { c.layout = static_cast<Layout>(7); }},
      {"rooms.min",
       [](SceneConfig& c) {
         c.layout = Layout::kRandomWalls, c.rooms = {0, 4};
       }},
      {"rooms.max",
       [](SceneConfig& c) {
         c.layout = Layout::kRandomWalls, c.rooms = {1, 9};
       }},
      {"rooms.max",
       [](SceneConfig& c) {
         c.layout = Layout::kRandomWalls, c.rooms = {3, 2};
       }},
  };
  for (const BadField& bad : cases) {
    SceneConfig config = SceneConfig::quadrant();
    bad.breaks(config);
    try {
      config.validate();
      ADD_FAILURE() << bad.field << ": no exception";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(bad.field), std::string::npos)
          << e.what() << " lacks " << bad.field;
      EXPECT_NE(std::string(e.what()).find("is invalid"), std::string::npos) << e.what();
    }
    // generate_scene validates too, before drawing anything.
    Rng rng(0, 0, 0);
    Scene s;
    EXPECT_THROW(generate_scene(config, rng, s), ConfigError) << bad.field;
  }
}

TEST(SceneConfigValidate, MessageNamesValueAndAllowedRange) {
  SceneConfig config = SceneConfig::quadrant();
  config.hiders.min = -1;
  try {
    config.validate();
    FAIL() << "no exception";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), "hiders.min = -1 is invalid: must be >= 0");
  }
}

TEST(SceneConfigValidate, TooManyBoxesForTheQuadrantRoomAreRejected) {
  SceneConfig config = SceneConfig::quadrant();
  config.boxes = {20, 20};
  try {
    config.validate();
    FAIL() << "no exception";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("boxes.max = 20"), std::string::npos) << what;
    EXPECT_NE(what.find("at most 16 boxes"), std::string::npos) << what;
  }
  config.boxes = {40, 40};
  EXPECT_THROW(config.validate(), ConfigError);
  // Hiders placed inside the room share its cells with the boxes.
  config = SceneConfig::quadrant();
  config.boxes = {14, 14};
  config.hider_uniform_placement = false;
  config.hiders = {6, 6};
  try {
    config.validate();
    FAIL() << "no exception";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("hiders.max"), std::string::npos) << e.what();
  }
  // The same counts elsewhere are fine.
  config.layout = Layout::kEmpty;
  EXPECT_NO_THROW(config.validate());
}

TEST(SceneConfigValidate, AcceptsWideButPossibleRanges) {
  SceneConfig config = SceneConfig::empty();
  config.hiders = {1, 2};
  config.seekers = {0, 2};
  config.boxes = {0, 4};
  config.elongated = {0, 4};
  config.ramps = {0, 2};
  EXPECT_NO_THROW(config.validate());
  // Elongated.min above boxes.min is allowed (the draw is capped by the box count).
  config = SceneConfig::full();
  config.boxes = {0, 9};
  EXPECT_NO_THROW(config.validate());
  // The paper's zero-shot team sizes and ramp counts.
  config.hiders = {4, 6};
  config.seekers = {4, 6};
  config.ramps = {3, 4};
  EXPECT_NO_THROW(config.validate());
  for (int seed = 0; seed < 100; ++seed) ASSERT_TRUE(valid_scene(config, make_scene(config, seed)));
}

}  // namespace
}  // namespace hns::physics
