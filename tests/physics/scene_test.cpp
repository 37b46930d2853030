// Scene generation (docs/game.md §1.3, §2.3-§2.6, §14.5): determinism, spawn validity over many seeds, the
// quadrant room and its doors, random rooms, wall geometry, config validation.
#include "physics/scene.hpp"

#include "physics/presets.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <vector>

namespace hns::physics {
namespace {

constexpr double kEps = 1e-9;

// ---------------------------------------------------------------------------------------------------------------
// Field-by-field equality (the structs are plain aggregates without operator==).
bool same(const WallCells& a, const WallCells& b) {
  return a.x1 == b.x1 && a.y1 == b.y1 && a.x2 == b.x2 && a.y2 == b.y2 && a.outer == b.outer;
}
bool same(const StaticBox& a, const StaticBox& b) {
  return a.cx == b.cx && a.cy == b.cy && a.cz == b.cz && a.hx == b.hx && a.hy == b.hy && a.hz == b.hz;
}
bool same(const DoorCells& a, const DoorCells& b) {
  return a.x1 == b.x1 && a.y1 == b.y1 && a.x2 == b.x2 && a.y2 == b.y2;
}
bool same(const Spawn& a, const Spawn& b) {
  return a.x == b.x && a.y == b.y && a.z == b.z && a.sx == b.sx && a.sy == b.sy && a.sz == b.sz;
}
template <typename T>
bool same(const std::vector<T>& a, const std::vector<T>& b) {
  if (a.size() != b.size()) return false;
  for (size_t k = 0; k < a.size(); ++k) {
    if (!same(a[k], b[k])) return false;
  }
  return true;
}
bool same(const Scene& a, const Scene& b) {
  return a.layout == b.layout && a.outer_walls == b.outer_walls && same(a.walls, b.walls) &&
         same(a.wall_boxes, b.wall_boxes) && same(a.doors, b.doors) && a.num_hiders == b.num_hiders &&
         a.num_seekers == b.num_seekers && same(a.agents, b.agents) && same(a.boxes, b.boxes) &&
         a.num_elongated == b.num_elongated && same(a.ramps, b.ramps) && a.regenerations == b.regenerations;
}

Scene make_scene(const SceneConfig& config, uint64_t seed, uint64_t world = 0, uint64_t episode = 0) {
  Rng rng(seed, world, episode);
  Scene scene;
  generate_scene(config, rng, scene);
  return scene;
}

// ---------------------------------------------------------------------------------------------------------------
// Footprints at spawn: agents are circles, boxes and ramps axis-aligned rectangles (yaw 0), walls rectangles.
struct Rect {
  double x0, y0, x1, y1;
};
Rect rect_of(const Spawn& s) {
  return {s.x - 0.5 * s.sx, s.y - 0.5 * s.sy, s.x + 0.5 * s.sx, s.y + 0.5 * s.sy};
}
Rect rect_of(const StaticBox& b) {
  return {b.cx - b.hx, b.cy - b.hy, b.cx + b.hx, b.cy + b.hy};
}

bool overlap(const Rect& a, const Rect& b) {
  return std::min(a.x1, b.x1) - std::max(a.x0, b.x0) > kEps &&
         std::min(a.y1, b.y1) - std::max(a.y0, b.y0) > kEps;
}
bool circle_overlaps(const Spawn& c, const Rect& r) {
  const double dx = std::clamp(c.x, r.x0, r.x1) - c.x, dy = std::clamp(c.y, r.y0, r.y1) - c.y;
  return std::sqrt(dx * dx + dy * dy) < kAgentRadius - kEps;
}
bool circles_overlap(const Spawn& a, const Spawn& b) {
  return std::hypot(a.x - b.x, a.y - b.y) < 2 * kAgentRadius - kEps;
}
bool inside(const Rect& r, double lo, double hi) {
  return r.x0 >= lo - kEps && r.y0 >= lo - kEps && r.x1 <= hi + kEps && r.y1 <= hi + kEps;
}

bool in_range(int n, const IntRange& r) {
  return n >= r.min && n <= r.max;
}
bool near(double a, double b) {
  return std::abs(a - b) < kEps;
}

enum class BoxKind { kXElongated, kYElongated, kCube };
BoxKind box_kind(const Spawn& b) {
  if (near(b.sx, kElongatedLong) && near(b.sy, kElongatedShort)) return BoxKind::kXElongated;
  if (near(b.sx, kElongatedShort) && near(b.sy, kElongatedLong)) return BoxKind::kYElongated;
  return BoxKind::kCube;
}

// Everything a valid scene of `config` satisfies, whatever the layout.
::testing::AssertionResult valid_scene(const SceneConfig& config, const Scene& s) {
  auto fail = [](const std::string& why) { return ::testing::AssertionFailure() << why; };
  if (s.layout != config.layout) return fail("layout differs from the config");
  // Counts and sizes.
  if (!in_range(s.num_hiders, config.hiders)) return fail("hider count out of range");
  if (!in_range(s.num_seekers, config.seekers)) return fail("seeker count out of range");
  if (int(s.agents.size()) != s.num_hiders + s.num_seekers) return fail("agents.size() != hiders + seekers");
  const int n_boxes = int(s.boxes.size());
  if (!in_range(n_boxes, config.boxes)) return fail("box count out of range");
  const int elongated_hi = std::min(config.elongated.max, n_boxes);
  if (s.num_elongated > elongated_hi || s.num_elongated < std::min(config.elongated.min, elongated_hi)) {
    return fail("elongated count out of range: " + std::to_string(s.num_elongated));
  }
  if (!in_range(int(s.ramps.size()), config.ramps)) return fail("ramp count out of range");
  for (const Spawn& a : s.agents) {
    if (!near(a.sx, 0.3) || !near(a.sy, 0.3) || !near(a.sz, 0.3) || !near(a.z, kAgentRadius)) {
      return fail("agent size or height");
    }
  }
  // Box index layout: x-elongated, then y-elongated, then cubes.
  int non_cubes = 0;
  for (int b = 0; b < n_boxes; ++b) {
    const Spawn& box = s.boxes[b];
    if (!near(box.sz, kBoxSize) || !near(box.z, 0.5 * kBoxSize)) return fail("box height");
    const BoxKind kind = box_kind(box);
    if (kind == BoxKind::kCube && (!near(box.sx, kBoxSize) || !near(box.sy, kBoxSize)))
      return fail("box size");
    if (b > 0 && kind < box_kind(s.boxes[b - 1])) return fail("box index layout out of order");
    non_cubes += kind != BoxKind::kCube;
  }
  if (non_cubes != s.num_elongated) return fail("num_elongated does not match the box sizes");
  for (const Spawn& r : s.ramps) {
    if (!near(r.sx, kRampSize) || !near(r.sy, kRampSize) || !near(r.sz, kRampSize) ||
        !near(r.z, 0.5 * kRampSize)) {
      return fail("ramp size or height");
    }
  }
  // Walls: outer walls exist exactly when outer_walls is set.
  const int outer =
      int(std::count_if(s.walls.begin(), s.walls.end(), [](const WallCells& w) { return w.outer; }));
  if (outer != (s.outer_walls ? 4 : 0)) return fail("outer wall count " + std::to_string(outer));
  // Every object inside the arena, off the outer wall cells (0 and 29); where the outer walls are dropped
  // their cells are free, but no placement reaches below cell 1.
  std::vector<Rect> rects;
  for (const Spawn& b : s.boxes) rects.push_back(rect_of(b));
  for (const Spawn& r : s.ramps) rects.push_back(rect_of(r));
  const double hi = kFloorSize - (s.outer_walls ? kCellSize : 0.0);
  for (const Spawn& a : s.agents) {
    if (!inside(rect_of(a), kCellSize, hi)) return fail("agent on an outer wall cell");
  }
  for (const Rect& r : rects) {
    if (!inside(r, kCellSize, hi)) return fail("box or ramp on an outer wall cell");
  }
  // No overlaps between objects, or with a wall.
  for (size_t a = 0; a < s.agents.size(); ++a) {
    for (size_t b = a + 1; b < s.agents.size(); ++b) {
      if (circles_overlap(s.agents[a], s.agents[b])) return fail("agents overlap");
    }
    for (const Rect& r : rects) {
      if (circle_overlaps(s.agents[a], r)) return fail("agent overlaps a box or ramp");
    }
    for (const StaticBox& w : s.wall_boxes) {
      if (circle_overlaps(s.agents[a], rect_of(w))) return fail("agent overlaps a wall");
    }
  }
  for (size_t a = 0; a < rects.size(); ++a) {
    for (size_t b = a + 1; b < rects.size(); ++b) {
      if (overlap(rects[a], rects[b])) return fail("boxes or ramps overlap");
    }
    for (const StaticBox& w : s.wall_boxes) {
      if (overlap(rects[a], rect_of(w))) return fail("box or ramp overlaps a wall");
    }
  }
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------------------------------------------------------
// Random rooms: each door joins two collinear interior pieces (one ending just before it, one starting just
// after it), and no piece borders two doors, so no interior wall has more than one door. A side's piece may
// be missing only where it would have been a single cell on another wall's line (the generator drops those).
// Collinear walls can meet end to end, so the pieces are matched to the doors by a small search. Returns the
// number of interior walls before door splitting, or -1 with `why`.
struct DoorNeighbours {
  std::vector<size_t> before, after;
};

bool match_doors(const std::vector<DoorNeighbours>& doors, size_t d, std::vector<bool>& used) {
  if (d == doors.size()) return true;
  for (size_t b : doors[d].before) {
    for (size_t a : doors[d].after) {
      if (used[a] || used[b]) continue;
      used[a] = used[b] = true;
      if (match_doors(doors, d + 1, used)) return true;
      used[a] = used[b] = false;
    }
  }
  return false;
}

int interior_walls(const Scene& s, std::string& why) {
  std::vector<WallCells> pieces;
  for (const WallCells& w : s.walls) {
    if (!w.outer) pieces.push_back(w);
  }
  // Whether cell (x, y) lies on the arena's edge or on a piece perpendicular to a wall along `vertical`.
  auto on_other_wall = [&](int x, int y, bool vertical) {
    if (x == 0 || y == 0 || x == kGridSize - 1 || y == kGridSize - 1) return true;
    for (const WallCells& w : s.walls) {
      if ((w.x1 == w.x2) == vertical) continue;
      if (x >= std::min(w.x1, w.x2) && x <= std::max(w.x1, w.x2) && y >= std::min(w.y1, w.y2) &&
          y <= std::max(w.y1, w.y2))
        return true;
    }
    return false;
  };
  size_t dropped = 0;  // single-cell pieces the generator dropped, each matched as a virtual piece
  std::vector<DoorNeighbours> neighbours;
  for (const DoorCells& d : s.doors) {
    const bool vertical = d.x1 == d.x2;
    const int first = vertical ? d.y1 : d.x1, last = vertical ? d.y2 : d.x2, line = vertical ? d.x1 : d.y1;
    if (last - first + 1 != 2) return why = "door is not 2 cells", -1;
    if (line == 0 || line == kGridSize - 1) return why = "door on an outer wall line", -1;
    DoorNeighbours n;
    for (size_t p = 0; p < pieces.size(); ++p) {
      const WallCells& w = pieces[p];
      const bool single = w.x1 == w.x2 && w.y1 == w.y2;
      if (!single && (w.x1 == w.x2) != vertical) continue;
      if ((vertical ? w.x1 : w.y1) != line) continue;
      const int lo = vertical ? std::min(w.y1, w.y2) : std::min(w.x1, w.x2);
      const int hi = vertical ? std::max(w.y1, w.y2) : std::max(w.x1, w.x2);
      if (lo <= last && hi >= first) return why = "a wall piece covers a door cell", -1;
      if (hi == first - 1) n.before.push_back(p);
      if (lo == last + 1) n.after.push_back(p);
    }
    const int before = first - 1, after = last + 1;
    if (on_other_wall(vertical ? line : before, vertical ? before : line, vertical))
      n.before.push_back(pieces.size() + dropped++);
    if (on_other_wall(vertical ? line : after, vertical ? after : line, vertical))
      n.after.push_back(pieces.size() + dropped++);
    neighbours.push_back(n);
  }
  std::vector<bool> used(pieces.size() + dropped, false);
  if (!match_doors(neighbours, 0, used)) return why = "doors do not each split one wall in two", -1;
  // Every real piece borders a door or is a wall without one; each virtual piece the match used was dropped.
  size_t virtual_used = 0;
  for (size_t v = pieces.size(); v < used.size(); ++v) virtual_used += used[v];
  return int(pieces.size() + virtual_used - s.doors.size());
}

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

// The registry is the one list of scenes: every row's name is unique and found by find_scene, its preset
// validates and is what world_preset returns, and its family agrees with the preset's task (the transfer
// family is what hns eval accepts, the probe what only hns counting runs).
TEST(SceneRegistry, EveryRowIsAValidPresetOfItsFamily) {
  std::set<std::string> names;
  for (const SceneInfo& s : kScenes) {
    SCOPED_TRACE(s.name);
    EXPECT_TRUE(names.insert(s.name).second);
    EXPECT_EQ(find_scene(s.name), &s);
    EXPECT_GT(std::string(s.summary).size(), 10u);
    const WorldConfig w = s.preset();
    EXPECT_NO_THROW(w.validate());
    EXPECT_EQ(world_preset(s.name).task, w.task);
    EXPECT_EQ(world_preset(s.name).scene.layout, w.scene.layout);
    const bool probe = w.task == WorldConfig::Task::kCounting;
    EXPECT_EQ(s.family == SceneFamily::kProbe, probe);
    EXPECT_EQ(s.family == SceneFamily::kTransfer, w.is_transfer_task() && !probe);
    EXPECT_EQ(s.family == SceneFamily::kFood,
              w.task == WorldConfig::Task::kHideAndSeek && w.scene.food.max > 0);
  }
  EXPECT_EQ(find_scene("moon"), nullptr);
  EXPECT_EQ(find_scene(""), nullptr);
  EXPECT_EQ(scene_names().size(), kScenes.size());
  EXPECT_EQ(scene_list(", ", SceneFamily::kTransfer),
            "lockbox, lock-and-return, sequential-lock, shelter, blueprint");
  try {
    (void)world_preset("moon");
    ADD_FAILURE() << "world_preset(\"moon\") did not throw";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("must be one of quadrant, full,"), std::string::npos) << e.what();
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

// The sequential-lock layout (docs/game.md §9.2 var_tri): two interior walls, no doors, three rooms whose free cells
// are everything the walls leave, one ramp per room.
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

// Dropped outer walls leave their cells free (docs/game.md §2.4: the grid is marked after the drop): team mates
// placed near their first member may then stand on the arena's last cell row or column; with the outer
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
