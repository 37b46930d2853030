// Scene generation (docs/game.md §1.3, §2.3-§2.6, §14.5): layout names, the scene config presets,
// determinism, spawn validity over many seeds, var_tri and the empty arena, rebuilds and failures. The
// quadrant room, random rooms and wall geometry are in scene_rooms_test.cpp, config validation in
// scene_config_test.cpp.
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
TEST(SceneLayout, ParsesNamesAndRejectsUnknownOnes) {
  for (Layout layout : {Layout::kEmpty, Layout::kQuadrant, Layout::kRandomWalls, Layout::kVarTri}) {
    EXPECT_EQ(parse_layout(layout_name(layout)), layout);
  }
  EXPECT_STREQ(layout_name(Layout::kRandomWalls), "randomwalls");
  try {
    parse_layout("rooms");
    FAIL() << "no exception";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    for (const char* needle : {"layout", "rooms", "empty", "quadrant", "randomwalls"}) {
      EXPECT_NE(what.find(needle), std::string::npos) << what << " lacks " << needle;
    }
  }
}

TEST(ScenePresets, MatchTheShippedConfigs) {
  const SceneConfig q = SceneConfig::quadrant();
  EXPECT_EQ(q.layout, Layout::kQuadrant);
  EXPECT_EQ(q.hiders.min, 2);
  EXPECT_EQ(q.seekers.max, 2);
  EXPECT_EQ(q.boxes.min, 2);
  EXPECT_EQ(q.boxes.max, 2);
  EXPECT_EQ(q.elongated.max, 0);
  EXPECT_EQ(q.ramps.max, 1);
  EXPECT_EQ(q.p_door_dropout, 0.5);
  EXPECT_TRUE(q.hider_uniform_placement);
  const SceneConfig f = SceneConfig::full();
  EXPECT_EQ(f.layout, Layout::kRandomWalls);
  EXPECT_EQ(f.hiders.min, 1);
  EXPECT_EQ(f.hiders.max, 3);
  EXPECT_EQ(f.seekers.max, 3);
  EXPECT_EQ(f.boxes.min, 3);
  EXPECT_EQ(f.boxes.max, 9);
  EXPECT_EQ(f.elongated.min, 3);
  EXPECT_EQ(f.ramps.min, 2);
  EXPECT_EQ(f.ramps.max, 2);
  EXPECT_EQ(f.rooms.min, 1);
  EXPECT_EQ(f.rooms.max, 4);
  EXPECT_EQ(f.prob_outside_walls, 0.5);
  EXPECT_EQ(f.together_radius, 0.5);
  EXPECT_EQ(SceneConfig::empty().layout, Layout::kEmpty);
  EXPECT_NO_THROW(q.validate());
  EXPECT_NO_THROW(f.validate());
  EXPECT_NO_THROW(SceneConfig::empty().validate());
}

TEST(SceneGeneration, SameStreamGivesTheSameSceneOtherEpisodesDiffer) {
  int differ = 0;
  const int seeds = 100;
  for (const SceneConfig& config : {SceneConfig::quadrant(), SceneConfig::full(), SceneConfig::empty()}) {
    for (int seed = 0; seed < seeds; ++seed) {
      const Scene a = make_scene(config, seed, 3, 7), b = make_scene(config, seed, 3, 7);
      ASSERT_TRUE(same(a, b)) << layout_name(config.layout) << " seed " << seed;
      differ += !same(a, make_scene(config, seed, 3, 8));
      differ += !same(a, make_scene(config, seed, 4, 7));
    }
  }
  EXPECT_GE(differ, 6 * seeds - 3);
}

TEST(SceneGeneration, ReusedOutputMatchesAFreshOne) {
  // One Scene reused across episodes (as at every reset) holds nothing from earlier scenes.
  Scene reused;
  for (int seed = 0; seed < 50; ++seed) {
    const SceneConfig config = seed % 2 ? SceneConfig::full() : SceneConfig::empty();
    Rng rng(seed, 0, 0);
    generate_scene(config, rng, reused);
    EXPECT_TRUE(same(reused, make_scene(config, seed))) << "seed " << seed;
  }
}

TEST(SceneGeneration, EveryPresetSpawnsValidScenes) {
  for (const SceneConfig& config : {SceneConfig::quadrant(), SceneConfig::full(), SceneConfig::empty()}) {
    for (int seed = 0; seed < 3000; ++seed) {
      const Scene s = make_scene(config, seed);
      ASSERT_TRUE(valid_scene(config, s)) << layout_name(config.layout) << " seed " << seed;
      if (s.outer_walls) {
        // Everything lies inside the outer walls' inner faces.
        for (const Spawn& a : s.agents) ASSERT_TRUE(inside(rect_of(a), 0.15, 5.85));
        for (const Spawn& b : s.boxes) ASSERT_TRUE(inside(rect_of(b), 0.15, 5.85));
        for (const Spawn& r : s.ramps) ASSERT_TRUE(inside(rect_of(r), 0.15, 5.85));
      }
    }
  }
}

// The sequential-lock layout (docs/game.md §9.2 var_tri): two interior walls, no doors, three rooms whose
// free cells are everything the walls leave, one ramp per room.
TEST(SceneVarTri, ThreeClosedRoomsOneRampEach) {
  SceneConfig config = SceneConfig::empty();
  config.layout = Layout::kVarTri;
  config.hiders = {1, 1};
  config.seekers = {0, 0};
  config.boxes = {4, 4};
  config.ramps = {3, 3};
  std::set<std::string> shapes;
  for (int seed = 0; seed < 500; ++seed) {
    const Scene s = make_scene(config, seed);
    ASSERT_TRUE(valid_scene(config, s)) << seed;
    ASSERT_EQ(s.walls.size(), 6u);
    ASSERT_TRUE(s.doors.empty());
    ASSERT_EQ(s.rooms.size(), 3u);
    std::vector<int> owner(size_t(kGridSize) * kGridSize, -1);  // room of each cell, -2 = wall
    for (const WallCells& w : s.walls) {
      for (int x = std::min(w.x1, w.x2); x <= std::max(w.x1, w.x2); ++x) {
        for (int y = std::min(w.y1, w.y2); y <= std::max(w.y1, w.y2); ++y) owner[x * kGridSize + y] = -2;
      }
    }
    int areas[3];
    for (int r = 0; r < 3; ++r) {
      const CellRect& room = s.rooms[r];
      areas[r] = (room.x1 - room.x0) * (room.y1 - room.y0);
      for (int x = room.x0; x < room.x1; ++x) {
        for (int y = room.y0; y < room.y1; ++y) {
          ASSERT_EQ(owner[x * kGridSize + y], -1)
              << "seed " << seed << ": room " << r << " overlaps a wall or room";
          owner[x * kGridSize + y] = r;
        }
      }
    }
    // Every cell is a wall's or a room's: the rooms are closed by the walls.
    ASSERT_EQ(std::count(owner.begin(), owner.end(), -1), 0) << seed;
    // Two rooms of about a quarter, one of about a half (the interior is 28 x 28 = 784 cells).
    EXPECT_GE(areas[0], 784 * 0.4 * 0.4 - 40) << seed;
    EXPECT_GE(areas[2], 784 * 0.4 - 40) << seed;
    EXPECT_LE(areas[2], 784 * 0.6) << seed;
    for (int r = 0; r < 3; ++r) {
      const CellRect& room = s.rooms[r];
      const Rect f = rect_of(s.ramps[r]);
      EXPECT_TRUE(f.x0 >= room.x0 * kCellSize - kEps && f.x1 <= room.x1 * kCellSize + kEps &&
                  f.y0 >= room.y0 * kCellSize - kEps && f.y1 <= room.y1 * kCellSize + kEps)
          << "seed " << seed << ": ramp " << r << " outside its room";
    }
    const WallCells& first = s.walls[4];
    shapes.insert(std::string(first.x1 == first.x2 ? "vertical" : "horizontal") +
                  (s.rooms[2].x0 == 1 && s.rooms[2].y0 == 1 ? " low" : " high"));
  }
  EXPECT_EQ(shapes.size(), 4u);  // both orientations, the split on either side
}

TEST(SceneGeneration, EmptyLayoutHasOnlyTheOuterWalls) {
  for (int seed = 0; seed < 200; ++seed) {
    const Scene s = make_scene(SceneConfig::empty(), seed);
    ASSERT_EQ(s.walls.size(), 4u);
    ASSERT_EQ(s.wall_boxes.size(), 4u);
    ASSERT_TRUE(s.doors.empty());
    for (const StaticBox& b : s.wall_boxes) EXPECT_NEAR(b.hz, 0.5 * kOuterWallHeight, kEps);
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Rebuilds and failures.
TEST(SceneGeneration, CrowdedScenesAreRebuiltUntilValid) {
  // Nine cubes in the quadrant room often need rebuilds; the result is still valid and counted.
  SceneConfig config = SceneConfig::quadrant();
  config.boxes = {9, 9};
  int rebuilt = 0;
  for (int seed = 0; seed < 100; ++seed) {
    const Scene s = make_scene(config, seed);
    ASSERT_TRUE(valid_scene(config, s)) << "seed " << seed;
    rebuilt += s.regenerations > 0;
  }
  EXPECT_GT(rebuilt, 10);
}

TEST(SceneGeneration, UnplaceableCountsFailWithAClearError) {
  // 15 cubes fit the quadrant room by area (validate passes) but never by random placement: the generator
  // gives up after max_regenerations rebuilds, which bounds this test's time.
  SceneConfig config = SceneConfig::quadrant();
  config.boxes = {15, 15};
  config.max_regenerations = 50;
  ASSERT_NO_THROW(config.validate());
  Rng rng(1, 0, 0);
  Scene s;
  try {
    generate_scene(config, rng, s);
    FAIL() << "no exception";
  } catch (const ConfigError&) {
    FAIL() << "a ConfigError, expected a runtime_error";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    for (const char* needle : {"box", "quadrant", "15 boxes", "50 rebuilds", "Lower"}) {
      EXPECT_NE(what.find(needle), std::string::npos) << what << " lacks " << needle;
    }
  }
}

}  // namespace
}  // namespace hns::physics
