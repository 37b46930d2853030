#include "batch/stage_stats.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hns::batch {
namespace {

using physics::kAgentRadius;
using physics::kCellSize;

// The footprint's four corners, counter-clockwise.
void corners(const Footprint& f, float out[4][2]) {
  const float sign[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
  for (int k = 0; k < 4; ++k) {
    const float u = sign[k][0] * f.hx, v = sign[k][1] * f.hy;
    out[k][0] = f.cx + f.c * u - f.s * v;
    out[k][1] = f.cy + f.s * u + f.c * v;
  }
}

// Distance from a point to the footprint (0 inside).
float point_distance(const Footprint& f, float x, float y) {
  const float dx = x - f.cx, dy = y - f.cy;
  const float u = f.c * dx + f.s * dy, v = -f.s * dx + f.c * dy;  // in the footprint's own axes
  const float ou = std::max(std::abs(u) - f.hx, 0.0f), ov = std::max(std::abs(v) - f.hy, 0.0f);
  return std::sqrt(ou * ou + ov * ov);
}

}  // namespace

Footprint footprint_of(const physics::StaticBox& box) {
  return Footprint{float(box.cx), float(box.cy), 1.0f, 0.0f, float(box.hx), float(box.hy)};
}

bool footprint_contains(const Footprint& f, float x, float y, float margin) {
  const float dx = x - f.cx, dy = y - f.cy;
  const float u = f.c * dx + f.s * dy, v = -f.s * dx + f.c * dy;
  return std::abs(u) <= f.hx + margin && std::abs(v) <= f.hy + margin;
}

// Two convex polygons that do not overlap are closest at a corner of one of them.
float footprint_distance(const Footprint& a, const Footprint& b) {
  float ca[4][2], cb[4][2];
  corners(a, ca);
  corners(b, cb);
  float best = std::numeric_limits<float>::max();
  for (int k = 0; k < 4; ++k) {
    best = std::min(best, point_distance(b, ca[k][0], ca[k][1]));
    best = std::min(best, point_distance(a, cb[k][0], cb[k][1]));
  }
  return best;
}

DoorGap door_gap(const physics::Scene& scene, const physics::DoorCells& door) {
  DoorGap g;
  g.axis = door.x1 == door.x2 ? 1 : 0;  // a door in a wall of constant x runs along y
  g.half_thickness = float(0.5 * physics::kWallThickness);
  // Cell k of the grid is centred on (k + 0.5) * kCellSize, as the wall boxes are (scene.cpp).
  const int fixed = g.axis == 1 ? door.x1 : door.y1;
  const int first = g.axis == 1 ? std::min(door.y1, door.y2) : std::min(door.x1, door.x2);
  const int last = g.axis == 1 ? std::max(door.y1, door.y2) : std::max(door.x1, door.x2);
  const double line = (fixed + 0.5) * kCellSize, mid = (0.5 * (first + last) + 0.5) * kCellSize;
  const double half = 0.5 * physics::kWallThickness;
  g.line = float(line);
  // Wall pieces end 0.15 m beyond the door's cells; where a one-cell piece was dropped the opening runs one
  // cell further, to the next wall's face. Farther is never this door: where both corner doors dropped the
  // room's corner piece, each door's opening stops there (the corner is open between them).
  constexpr double kReach = 0.15 + kCellSize;
  double lo = std::max(0.0, first * kCellSize - kReach);
  double hi = std::min(physics::kFloorSize, (last + 1) * kCellSize + kReach);
  // The opening ends where a wall box that crosses or touches the wall's line begins (in double, with a
  // tolerance: a perpendicular wall's face lies exactly on the line's edge).
  for (const physics::StaticBox& w : scene.wall_boxes) {
    const double along_c = g.axis == 0 ? w.cx : w.cy, along_h = g.axis == 0 ? w.hx : w.hy;
    const double across_c = g.axis == 0 ? w.cy : w.cx, across_h = g.axis == 0 ? w.hy : w.hx;
    if (std::abs(across_c - line) > across_h + half + 1e-6) continue;
    const double begin = along_c - along_h, end = along_c + along_h;
    if (end <= mid) lo = std::max(lo, end);
    if (begin >= mid) hi = std::min(hi, begin);
    if (begin < mid && end > mid) lo = hi = mid;  // a wall across the door's cells: no opening
  }
  g.lo = float(lo);
  g.hi = float(hi);
  return g;
}

bool door_sealed(const DoorGap& gap, std::span<const Footprint> boxes) {
  const float width = float(2.0 * kAgentRadius);  // an agent's diameter
  if (gap.hi - gap.lo < width) return true;       // no agent fits through even an empty opening
  for (int side = -1; side <= 1; side += 2) {
    // Extend the covered stretch [lo, pos] greedily: a box that starts less than `width` past pos leaves no
    // passable stretch before it, so the cover reaches its far end.
    float pos = gap.lo;
    for (;;) {
      float reach = pos;
      for (const Footprint& f : boxes) {
        float cs[4][2];
        corners(f, cs);
        float u0 = std::numeric_limits<float>::max(), u1 = -u0, v0 = u0, v1 = -u0;
        for (const auto& p : cs) {
          const float u = gap.axis == 0 ? p[0] : p[1], v = (gap.axis == 0 ? p[1] : p[0]) - gap.line;
          u0 = std::min(u0, u), u1 = std::max(u1, u);
          v0 = std::min(v0, v), v1 = std::max(v1, v);
        }
        // Clearance between the box and the wall's face on this side (0 for a box in the opening).
        const bool in_opening = v0 < gap.half_thickness && v1 > -gap.half_thickness;
        const float clearance = in_opening ? 0.0f
                                : side > 0 ? v0 - gap.half_thickness
                                           : -v1 - gap.half_thickness;
        if (clearance < 0.0f || clearance >= width) continue;  // the other side, or an agent fits behind it
        if (u0 < pos + width && u1 > reach) reach = u1;        // what is left before it is too narrow to pass
      }
      if (reach >= gap.hi || gap.hi - pos < width) return true;
      if (reach <= pos) break;  // a free stretch of at least `width` from pos: open on this side
      pos = reach;
    }
  }
  return false;
}

bool hider_screened(std::span<const Footprint> boxes, float x, float y, float z) {
  if (z > kHighAgentZ) return false;
  const float reach = float(kAgentRadius) + kScreenGap;  // from the hider's centre
  for (const Footprint& f : boxes) {
    if (point_distance(f, x, y) < reach) return true;
  }
  return false;
}

Rect quadrant_room() {
  // Room walls on grid row and column kQuadrantSize (docs/game.md §2.3), outer walls on 0 and 29; the
  // interior runs from one wall box's face to the other's.
  constexpr int kRoomWall = physics::kQuadrantSize, kLast = physics::kGridSize - 1;
  const float h = float(0.5 * physics::kWallThickness);
  return Rect{float((kRoomWall + 0.5) * kCellSize) + h, float(0.5 * kCellSize) + h,
              float((kLast + 0.5) * kCellSize) - h, float((kRoomWall + 0.5) * kCellSize) - h};
}

bool stands_on(const Footprint& box, float box_top_z, float agent_x, float agent_y, float agent_z) {
  const float above = agent_z - box_top_z;
  return above > 0.05f && above < float(2.0 * kAgentRadius) + 0.05f &&
         footprint_contains(box, agent_x, agent_y);
}

}  // namespace hns::batch
