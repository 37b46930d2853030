// What the scene tests share (scene_test.cpp, scene_rooms_test.cpp, scene_config_test.cpp): scene equality,
// generation from a seed, overlap geometry, and the validity checks every generated scene must pass.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "physics/scene.hpp"

namespace hns::physics::scene_test {

inline constexpr double kEps = 1e-9;

// ---------------------------------------------------------------------------------------------------------------
// Field-by-field equality (the structs are plain aggregates without operator==).
inline bool same(const WallCells& a, const WallCells& b) {
  return a.x1 == b.x1 && a.y1 == b.y1 && a.x2 == b.x2 && a.y2 == b.y2 && a.outer == b.outer;
}
inline bool same(const StaticBox& a, const StaticBox& b) {
  return a.cx == b.cx && a.cy == b.cy && a.cz == b.cz && a.hx == b.hx && a.hy == b.hy && a.hz == b.hz;
}
inline bool same(const DoorCells& a, const DoorCells& b) {
  return a.x1 == b.x1 && a.y1 == b.y1 && a.x2 == b.x2 && a.y2 == b.y2;
}
inline bool same(const Spawn& a, const Spawn& b) {
  return a.x == b.x && a.y == b.y && a.z == b.z && a.sx == b.sx && a.sy == b.sy && a.sz == b.sz;
}
template <typename T>
inline bool same(const std::vector<T>& a, const std::vector<T>& b) {
  if (a.size() != b.size()) return false;
  for (size_t k = 0; k < a.size(); ++k) {
    if (!same(a[k], b[k])) return false;
  }
  return true;
}
inline bool same(const Scene& a, const Scene& b) {
  return a.layout == b.layout && a.outer_walls == b.outer_walls && same(a.walls, b.walls) &&
         same(a.wall_boxes, b.wall_boxes) && same(a.doors, b.doors) && a.num_hiders == b.num_hiders &&
         a.num_seekers == b.num_seekers && same(a.agents, b.agents) && same(a.boxes, b.boxes) &&
         a.num_elongated == b.num_elongated && same(a.ramps, b.ramps) && a.regenerations == b.regenerations;
}

inline Scene make_scene(const SceneConfig& config, uint64_t seed, uint64_t world = 0, uint64_t episode = 0) {
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
inline Rect rect_of(const Spawn& s) {
  return {s.x - 0.5 * s.sx, s.y - 0.5 * s.sy, s.x + 0.5 * s.sx, s.y + 0.5 * s.sy};
}
inline Rect rect_of(const StaticBox& b) {
  return {b.cx - b.hx, b.cy - b.hy, b.cx + b.hx, b.cy + b.hy};
}

inline bool overlap(const Rect& a, const Rect& b) {
  return std::min(a.x1, b.x1) - std::max(a.x0, b.x0) > kEps &&
         std::min(a.y1, b.y1) - std::max(a.y0, b.y0) > kEps;
}
inline bool circle_overlaps(const Spawn& c, const Rect& r) {
  const double dx = std::clamp(c.x, r.x0, r.x1) - c.x, dy = std::clamp(c.y, r.y0, r.y1) - c.y;
  return std::sqrt(dx * dx + dy * dy) < kAgentRadius - kEps;
}
inline bool circles_overlap(const Spawn& a, const Spawn& b) {
  return std::hypot(a.x - b.x, a.y - b.y) < 2 * kAgentRadius - kEps;
}
inline bool inside(const Rect& r, double lo, double hi) {
  return r.x0 >= lo - kEps && r.y0 >= lo - kEps && r.x1 <= hi + kEps && r.y1 <= hi + kEps;
}

inline bool in_range(int n, const IntRange& r) {
  return n >= r.min && n <= r.max;
}
inline bool near(double a, double b) {
  return std::abs(a - b) < kEps;
}

enum class BoxKind { kXElongated, kYElongated, kCube };
inline BoxKind box_kind(const Spawn& b) {
  if (near(b.sx, kElongatedLong) && near(b.sy, kElongatedShort)) return BoxKind::kXElongated;
  if (near(b.sx, kElongatedShort) && near(b.sy, kElongatedLong)) return BoxKind::kYElongated;
  return BoxKind::kCube;
}

// Everything a valid scene of `config` satisfies, whatever the layout.
inline ::testing::AssertionResult valid_scene(const SceneConfig& config, const Scene& s) {
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

inline bool match_doors(const std::vector<DoorNeighbours>& doors, size_t d, std::vector<bool>& used) {
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

inline int interior_walls(const Scene& s, std::string& why) {
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
}  // namespace hns::physics::scene_test
