// Scene generation's rooms (docs/game.md §2.3-§2.6, §14.5): the quadrant room and its doors, wall geometry,
// the full game's random rooms, outer walls, team placement and counts.
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
// Quadrant game (docs/game.md §2.3, §2.5).
bool in_room(double x, double y) {
  return x > 3.1 && y < 3.1;
}

TEST(SceneQuadrant, BoxesStartInsideTheRoomSeekersOutside) {
  const SceneConfig config = SceneConfig::quadrant();
  int hiders_outside = 0;
  for (int seed = 0; seed < 2000; ++seed) {
    const Scene s = make_scene(config, seed);
    for (const Spawn& b : s.boxes) {
      const Rect r = rect_of(b);
      ASSERT_TRUE(r.x0 >= 3.15 - kEps && r.x1 <= 5.85 + kEps && r.y0 >= 0.15 - kEps && r.y1 <= 3.05 + kEps)
          << "seed " << seed << " box at " << b.x << ", " << b.y;
    }
    for (int a = s.num_hiders; a < int(s.agents.size()); ++a) {
      ASSERT_FALSE(in_room(s.agents[a].x, s.agents[a].y)) << "seed " << seed << " seeker " << a;
    }
    for (int a = 0; a < s.num_hiders; ++a) hiders_outside += !in_room(s.agents[a].x, s.agents[a].y);
  }
  // Uniform hider placement: hiders start anywhere, mostly outside the room.
  EXPECT_GT(hiders_outside, 2000);
}

TEST(SceneQuadrant, HidersStartInTheRoomWithoutUniformPlacement) {
  SceneConfig config = SceneConfig::quadrant();
  config.hider_uniform_placement = false;
  for (int seed = 0; seed < 500; ++seed) {
    const Scene s = make_scene(config, seed);
    ASSERT_TRUE(valid_scene(config, s));
    for (int a = 0; a < s.num_hiders; ++a)
      ASSERT_TRUE(in_room(s.agents[a].x, s.agents[a].y)) << "seed " << seed;
  }
}

TEST(SceneQuadrant, DoorsAreTwoCellsOnTheRoomWallsOneOrTwoOfThem) {
  const SceneConfig config = SceneConfig::quadrant();
  int scenes_with[3] = {0, 0, 0};
  std::set<int> vertical_starts, horizontal_starts;
  for (int seed = 0; seed < 2000; ++seed) {
    const Scene s = make_scene(config, seed);
    ASSERT_TRUE(s.doors.size() == 1 || s.doors.size() == 2) << "seed " << seed;
    ++scenes_with[s.doors.size()];
    int on_vertical = 0, on_horizontal = 0;
    for (const DoorCells& d : s.doors) {
      if (d.x1 == 15 && d.x2 == 15) {
        // Vertical room wall, cells (15, 0)-(15, 15): offsets 1 … 13 from its start.
        ASSERT_EQ(d.y2 - d.y1, 1);
        ASSERT_GE(d.y1, 1);
        ASSERT_LE(d.y1, 13);
        vertical_starts.insert(d.y1);
        ++on_vertical;
      } else {
        // Horizontal room wall, cells (15, 15)-(29, 15): offsets 1 … 12 from its start.
        ASSERT_EQ(d.y1, 15);
        ASSERT_EQ(d.y2, 15);
        ASSERT_EQ(d.x2 - d.x1, 1);
        ASSERT_GE(d.x1, 16);
        ASSERT_LE(d.x1, 27);
        horizontal_starts.insert(d.x1);
        ++on_horizontal;
      }
    }
    ASSERT_LE(on_vertical, 1);
    ASSERT_LE(on_horizontal, 1);
    // Room walls: two pieces per door, one for a wall without a door, less the pieces of a single cell (a
    // door one cell from either end of its wall); outer walls stay whole.
    size_t stubs = 0;
    for (const DoorCells& d : s.doors) {
      const bool vertical = d.x1 == 15 && d.x2 == 15;
      const int first = vertical ? d.y1 : d.x1, wall_start = vertical ? 0 : 15, wall_end = vertical ? 15 : 29;
      stubs += (first - 1 == wall_start) + (first + 2 == wall_end);
    }
    ASSERT_EQ(s.walls.size(), 4 + 2 + s.doors.size() - stubs) << "seed " << seed;
  }
  EXPECT_GT(scenes_with[1], 800);
  EXPECT_GT(scenes_with[2], 800);
  EXPECT_EQ(vertical_starts.size(), 13u);
  EXPECT_EQ(horizontal_starts.size(), 12u);
}

TEST(SceneQuadrant, DoorDropoutProbabilityIsHonoured) {
  SceneConfig config = SceneConfig::quadrant();
  config.p_door_dropout = 0.0;
  for (int seed = 0; seed < 200; ++seed) ASSERT_EQ(make_scene(config, seed).doors.size(), 2u);
  config.p_door_dropout = 1.0;
  for (int seed = 0; seed < 200; ++seed) ASSERT_EQ(make_scene(config, seed).doors.size(), 1u);
}

TEST(SceneQuadrant, WallGeometry) {
  const SceneConfig config = SceneConfig::quadrant();
  int gaps_checked = 0;
  for (int seed = 0; seed < 300; ++seed) {
    const Scene s = make_scene(config, seed);
    int low_faces = 0, high_faces = 0;
    for (const StaticBox& b : s.wall_boxes) {
      if (near(b.hz, 0.5 * kOuterWallHeight)) {
        // Outer walls: 4 m high, 0.1 m thick, inner faces at 0.15 and 5.85.
        EXPECT_NEAR(b.cz, 2.0, kEps);
        EXPECT_NEAR(std::min(b.hx, b.hy), 0.05, kEps);
        EXPECT_NEAR(std::max(b.hx, b.hy), 2.85, kEps);
        const double centre = b.hx < b.hy ? b.cx : b.cy;
        if (centre < 3) {
          EXPECT_NEAR(centre + 0.05, 0.15, kEps);
          ++low_faces;
        } else {
          EXPECT_NEAR(centre - 0.05, 5.85, kEps);
          ++high_faces;
        }
      } else {
        // Room walls: 0.5 m high, centred on 3.1 m.
        ASSERT_NEAR(b.hz, 0.5 * kInteriorWallHeight, kEps);
        EXPECT_NEAR(b.cz, 0.25, kEps);
        EXPECT_TRUE(near(b.cx, 3.1) || near(b.cy, 3.1)) << b.cx << ", " << b.cy;
      }
    }
    EXPECT_EQ(low_faces, 2);
    EXPECT_EQ(high_faces, 2);
    // A door's opening between the facing ends of its two wall pieces is 0.7 m.
    for (const DoorCells& d : s.doors) {
      const bool vertical = d.x1 == d.x2;
      const double door_mid = 0.5 * ((vertical ? d.y1 + d.y2 : d.x1 + d.x2) + 1) * kCellSize;
      double below = -1e9, above = 1e9;
      const double line = ((vertical ? d.x1 : d.y1) + 0.5) * kCellSize;
      for (const StaticBox& b : s.wall_boxes) {
        // Boxes on the door's line (a 2-cell piece is a 0.1 m square post).
        if (!near(b.hz, 0.5 * kInteriorWallHeight) || !near(vertical ? b.cx : b.cy, line)) continue;
        if (!near(vertical ? b.hx : b.hy, 0.5 * kWallThickness)) continue;
        const double c = vertical ? b.cy : b.cx, h = vertical ? b.hy : b.hx;
        if (c < door_mid) below = std::max(below, c + h);
        if (c > door_mid) above = std::min(above, c - h);
      }
      // A piece of one cell has no physical box; only doors with both neighbours present are measured.
      if (below > 0 && above < 6 && door_mid - below < 0.5 && above - door_mid < 0.5) {
        EXPECT_NEAR(above - below, 0.7, 1e-9) << "seed " << seed;
        ++gaps_checked;
      }
    }
  }
  EXPECT_GT(gaps_checked, 300);
}

TEST(SceneWalls, PhysicalBoxesFollowTheCells) {
  // Every piece of >= 2 cells becomes one box from centre to centre less 0.05 m per end; 1-cell pieces none.
  for (const SceneConfig& config : {SceneConfig::quadrant(), SceneConfig::full()}) {
    for (int seed = 0; seed < 500; ++seed) {
      const Scene s = make_scene(config, seed);
      size_t expected = 0;
      for (const WallCells& w : s.walls) {
        const int cells = std::abs(w.x2 - w.x1) + std::abs(w.y2 - w.y1) + 1;
        if (cells < 2) continue;
        const double length = (cells - 1) * kCellSize - kWallThickness;
        const double cx = 0.5 * (w.x1 + w.x2 + 1) * kCellSize, cy = 0.5 * (w.y1 + w.y2 + 1) * kCellSize;
        ASSERT_LT(expected, s.wall_boxes.size());
        const StaticBox& b = s.wall_boxes[expected++];
        EXPECT_NEAR(b.cx, cx, kEps);
        EXPECT_NEAR(b.cy, cy, kEps);
        EXPECT_NEAR(2 * std::max(b.hx, b.hy), length, kEps);
        EXPECT_NEAR(2 * std::min(b.hx, b.hy), kWallThickness, kEps);
        EXPECT_NEAR(2 * b.hz, w.outer ? kOuterWallHeight : kInteriorWallHeight, kEps);
      }
      EXPECT_EQ(expected, s.wall_boxes.size()) << layout_name(config.layout) << " seed " << seed;
    }
  }
}

// The original drops wall pieces of a single cell (a door one cell from a wall's end): none is left, in
// either game.
TEST(SceneWalls, NoPieceOfASingleCell) {
  for (const SceneConfig& config : {SceneConfig::quadrant(), SceneConfig::full()}) {
    for (int seed = 0; seed < 2000; ++seed) {
      const Scene s = make_scene(config, seed);
      for (const WallCells& w : s.walls) {
        ASSERT_FALSE(w.x1 == w.x2 && w.y1 == w.y2) << layout_name(config.layout) << " seed " << seed
                                                   << ": piece at (" << w.x1 << ", " << w.y1 << ")";
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Full game (docs/game.md §2.4, §2.6, §14.5).

// Dropped outer walls leave their cells free (docs/game.md §2.4: the grid is marked after the drop): team
// mates placed near their first member may then stand on the arena's last cell row or column; with the outer
// walls kept they never do.
TEST(SceneFull, DroppedOuterWallsFreeTheirCells) {
  const SceneConfig config = SceneConfig::full();
  int on_edge_cells[2] = {0, 0};  // scenes with an agent on cell row/column 29: outer walls dropped, kept
  for (int seed = 0; seed < 3000; ++seed) {
    const Scene s = make_scene(config, seed);
    ASSERT_EQ(s.walls.size() >= 4 && s.walls[0].outer, s.outer_walls) << "seed " << seed;
    for (const WallCells& w : s.walls) ASSERT_TRUE(!w.outer || s.outer_walls) << "seed " << seed;
    bool edge = false;
    for (const Spawn& a : s.agents)
      edge = edge || a.x + 0.5 * a.sx > 5.8 + kEps || a.y + 0.5 * a.sy > 5.8 + kEps;
    on_edge_cells[s.outer_walls ? 1 : 0] += edge;
  }
  EXPECT_GT(on_edge_cells[0], 5);
  EXPECT_EQ(on_edge_cells[1], 0);
}
TEST(SceneFull, RoomsDoorsOuterWallsAndCounts) {
  const SceneConfig config = SceneConfig::full();
  const int n = 2000;
  int with_outer = 0;
  std::set<int> room_counts, hider_counts, seeker_counts, box_counts;
  int x_elongated = 0, y_elongated = 0;
  for (int seed = 0; seed < n; ++seed) {
    const Scene s = make_scene(config, seed);
    with_outer += s.outer_walls;
    ASSERT_GE(s.num_elongated, 3) << "seed " << seed;
    std::string why;
    const int walls = interior_walls(s, why);
    ASSERT_GE(walls, 0) << "seed " << seed << ": " << why;
    room_counts.insert(walls + 1);
    hider_counts.insert(s.num_hiders);
    seeker_counts.insert(s.num_seekers);
    box_counts.insert(int(s.boxes.size()));
    for (const Spawn& b : s.boxes) {
      x_elongated += box_kind(b) == BoxKind::kXElongated;
      y_elongated += box_kind(b) == BoxKind::kYElongated;
    }
    for (const WallCells& w : s.walls) ASSERT_TRUE(w.x1 == w.x2 || w.y1 == w.y2);
  }
  EXPECT_EQ(room_counts, (std::set<int>{1, 2, 3, 4}));
  EXPECT_EQ(hider_counts, (std::set<int>{1, 2, 3}));
  EXPECT_EQ(seeker_counts, (std::set<int>{1, 2, 3}));
  EXPECT_EQ(box_counts, (std::set<int>{3, 4, 5, 6, 7, 8, 9}));
  EXPECT_GT(x_elongated, 0);
  EXPECT_GT(y_elongated, 0);
  EXPECT_GT(with_outer, 0.4 * n);
  EXPECT_LT(with_outer, 0.6 * n);
}

TEST(SceneFull, TeamMatesSpawnNearTheirFirstMember) {
  // r = ceil(0.5 / 0.2) = 3 cells around the first member's cell, plus the jitter: at most 0.7 m per axis.
  const SceneConfig config = SceneConfig::full();
  for (int seed = 0; seed < 1000; ++seed) {
    const Scene s = make_scene(config, seed);
    for (int a = 0; a < int(s.agents.size()); ++a) {
      const int first = a < s.num_hiders ? 0 : s.num_hiders;
      EXPECT_LE(std::abs(s.agents[a].x - s.agents[first].x), 0.7 + kEps) << "seed " << seed;
      EXPECT_LE(std::abs(s.agents[a].y - s.agents[first].y), 0.7 + kEps) << "seed " << seed;
    }
  }
}

// The paper's intrinsic-motivation baselines start everything movable in a quarter of the arena: with
// spawn_quarter every agent, box and ramp lies inside x, y in [0.2, 3.0] m, in the quadrant game (whose room
// is another quarter) and on random rooms alike, spread over the whole quarter.
TEST(SceneGeneration, SpawnQuarterPutsAgentsBoxesAndRampsInOneQuarter) {
  SceneConfig full = SceneConfig::full();
  full.hiders = {1, 1};
  full.seekers = {0, 0};
  for (SceneConfig config : {SceneConfig::quadrant(), full}) {
    config.spawn_quarter = true;
    double lo_x = 6, hi_x = 0, lo_y = 6, hi_y = 0;
    for (int seed = 0; seed < 500; ++seed) {
      const Scene s = make_scene(config, seed);
      ASSERT_TRUE(valid_scene(config, s)) << "seed " << seed;
      std::vector<Spawn> movable = s.agents;
      movable.insert(movable.end(), s.boxes.begin(), s.boxes.end());
      movable.insert(movable.end(), s.ramps.begin(), s.ramps.end());
      for (const Spawn& m : movable) {
        const Rect r = rect_of(m);
        ASSERT_TRUE(r.x0 >= 0.2 - kEps && r.x1 <= 3.0 + kEps && r.y0 >= 0.2 - kEps && r.y1 <= 3.0 + kEps)
            << "seed " << seed << " object at " << m.x << ", " << m.y;
        lo_x = std::min(lo_x, m.x), hi_x = std::max(hi_x, m.x);
        lo_y = std::min(lo_y, m.y), hi_y = std::max(hi_y, m.y);
      }
    }
    EXPECT_LT(lo_x, 0.6);
    EXPECT_GT(hi_x, 2.6);
    EXPECT_LT(lo_y, 0.6);
    EXPECT_GT(hi_y, 2.6);
  }
  // Without the flag the same scenes use the whole arena.
  bool outside = false;
  for (int seed = 0; seed < 50 && !outside; ++seed)
    for (const Spawn& b : make_scene(full, seed).boxes) outside = outside || b.x > 3.2 || b.y > 3.2;
  EXPECT_TRUE(outside);
}

TEST(SceneFull, UpToEightRoomsCanBeBuilt) {
  SceneConfig config = SceneConfig::full();
  config.rooms = {8, 8};
  for (int seed = 0; seed < 200; ++seed) {
    const Scene s = make_scene(config, seed);
    ASSERT_TRUE(valid_scene(config, s));
    std::string why;
    ASSERT_EQ(interior_walls(s, why), 7) << "seed " << seed << ": " << why;
  }
}

TEST(SceneFull, FewerBoxesThanElongatedMinMakesThemAllElongated) {
  SceneConfig config = SceneConfig::full();
  config.boxes = {0, 4};
  config.elongated = {3, 9};
  std::set<int> counts;
  for (int seed = 0; seed < 500; ++seed) {
    const Scene s = make_scene(config, seed);
    ASSERT_TRUE(valid_scene(config, s));
    ASSERT_EQ(s.num_elongated, std::min<int>(int(s.boxes.size()), std::max(3, s.num_elongated)));
    counts.insert(int(s.boxes.size()));
  }
  EXPECT_EQ(counts, (std::set<int>{0, 1, 2, 3, 4}));
}

}  // namespace
}  // namespace hns::physics
