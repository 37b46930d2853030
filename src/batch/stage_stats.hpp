// Geometry behind the stage detectors (docs/training.md "Stages"): whether locked boxes seal a door, how
// close a ramp comes to a wall, whether a seeker stands on a box. Pure functions of a few bodies; BatchSim
// evaluates them on an env's SoA mirror once per step (seeking phase) or once per episode (end of prep).
#pragma once

#include <span>

#include "physics/scene.hpp"

namespace hns::batch {

// A body's footprint on the floor: a rectangle given by its centre (m), yaw as (cos, sin) and half extents
// along its own axes (m).
struct Footprint {
  float cx = 0, cy = 0;
  float c = 1, s = 0;
  float hx = 0, hy = 0;
};

// Footprint of an axis-aligned static box (a wall piece).
Footprint footprint_of(const physics::StaticBox& box);

// Shortest 2-D distance between two footprints, m; 0 when one has a corner inside the other. (Two
// rectangles that cross without either holding a corner of the other, a plus sign, also read as apart:
// bodies cannot get there.)
float footprint_distance(const Footprint& a, const Footprint& b);

// True if the point (x, y) lies inside the footprint grown by `margin` m on every side.
bool footprint_contains(const Footprint& f, float x, float y, float margin = 0.0f);

// A door's opening. The wall's centre line runs along `axis` (0: x, 1: y) at coordinate `line` of the other
// axis; the opening is [lo, hi] along the wall, the free stretch between the wall boxes on either side of
// the door's cells (m). half_thickness: half the wall's thickness (m).
struct DoorGap {
  int axis = 0;
  float line = 0, half_thickness = 0;
  float lo = 0, hi = 0;
};

DoorGap door_gap(const physics::Scene& scene, const physics::DoorCells& door);

// Whether locked boxes seal a door. On either side of the wall, take the boxes that stand in the opening or
// within an agent's diameter (2 x kAgentRadius) of the wall's face (no agent fits between them and the
// wall), and project them onto the wall: the door is sealed when, on one side, no stretch of the opening at
// least an agent's diameter wide is left uncovered. Boxes of any shape count; the caller passes the locked
// ones.
bool door_sealed(const DoorGap& gap, std::span<const Footprint> boxes);

// Whether a hider at (x, y) stands beside one of the boxes (the caller passes the locked ones): less than an
// agent's diameter (2 x kAgentRadius) between its body and a box's footprint, so no seeker fits between
// them; the box screens the hider from that side. The shelter of locked boxes that hiders build in a corner
// of the quadrant room, instead of sealing its doors, shows as hiders beside locked boxes at the end of the
// preparation phase. A hider standing on something (its centre above kHighAgentZ, such as on top of a box)
// is in plain view and not screened.
inline constexpr float kScreenGap = float(2.0 * physics::kAgentRadius);
bool hider_screened(std::span<const Footprint> boxes, float x, float y, float z);

// Axis-aligned rectangle, m.
struct Rect {
  float x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool contains(float x, float y) const { return x >= x0 && x <= x1 && y >= y0 && y <= y1; }
};

// The quadrant room's interior (docs/game.md §2.3): x in [3.15, 5.85], y in [0.15, 3.05].
Rect quadrant_room();

// Height of an agent's centre above which it stands higher than an interior wall (on a box, a ramp's top
// or a wall): kInteriorWallHeight + kAgentRadius - 0.05 = 0.6 m.
inline constexpr float kHighAgentZ = float(physics::kInteriorWallHeight + physics::kAgentRadius - 0.05);

// A seeker "surfs" a box when it stands on it (its centre above the box's footprint, 0.05-0.35 m above the
// box's top) while the box slides at kSurfSpeed or more; an episode counts as box surfing from
// kSurfSteps such steps on.
inline constexpr float kSurfSpeed = 0.5f;  // m/s, horizontal
inline constexpr int kSurfSteps = 3;
bool stands_on(const Footprint& box, float box_top_z, float agent_x, float agent_y, float agent_z);

}  // namespace hns::batch
