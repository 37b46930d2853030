// Scalar geometry of the game world: ray casts against walls, boxes, ramps and agents, the vision cone,
// line of sight, lidar and point-to-cuboid distance (docs/game.md §3.3, §4.1, §4.2, §14.6, §14.7).
// These are the reference implementations; the batch layer's SIMD kernels are tested against them.
#pragma once

#include <cstdint>
#include <span>

namespace hns::physics {

inline constexpr double kVisionHalfAngle = 3.0 * 3.14159265358979323846 / 8.0;  // rad, 135° cone
inline constexpr int kLidarRays = 30;       // world-fixed, angle 2πk/30 from +x
inline constexpr double kLidarRange = 6.0;  // m; no hit or a farther hit reads 6 (§14.6)
inline constexpr double kRampHalf = 0.25;   // m, half extent of the ramp's bounding box
// The ramp's volume centroid in its bounding-box frame (docs/game.md §1.2): the ODE body origin and the point
// lines of sight aim at. It lies inside the solid, (1/6)/√2 ≈ 0.118 m from the slope, its nearest face.
inline constexpr double kRampCentroidY = -1.0 / 12.0;  // m
inline constexpr double kRampCentroidZ = -1.0 / 12.0;  // m
// Half extents of the ramp's grab and lock reach cuboid about its bounding-box centre, along the ramp's body
// axes (docs/game.md §3.3: the original's mesh geom_size).
inline constexpr double kRampReachHalf[3] = {0.2357, 0.25, 0.3536};  // m
// An agent's two massless arm spheres on its front (-y) side, body frame (docs/game.md §1.2). They collide,
// occlude and are hit by lidar as part of the agent.
inline constexpr double kArmRadius = 0.05;                                                   // m
inline constexpr double kArmOffset[2][3] = {{-0.13, -0.075, -0.05}, {0.13, -0.075, -0.05}};  // m
// A ball about an agent's centre that holds its body and both arms (|kArmOffset| + kArmRadius = 0.2082 m).
inline constexpr double kAgentReach = 0.21;  // m
static_assert((kAgentReach - kArmRadius) * (kAgentReach - kArmRadius) >=
                  kArmOffset[0][0] * kArmOffset[0][0] + kArmOffset[0][1] * kArmOffset[0][1] +
                      kArmOffset[0][2] * kArmOffset[0][2],
              "the agent's reach must hold its arms");

// A yaw-rotated box: centre (m), half extents (m), yaw as cos/sin. Walls have c = 1, s = 0.
struct OrientedBox {
  double cx, cy, cz;
  double hx, hy, hz;
  double c, s;
};

// A ramp: its bounding-box centre (m) and yaw. In its own frame the wedge is
// x ∈ [-h, h], y >= -h, z >= -h, y + z <= 0 (back face at y = -h, slope rising toward -y), h = 0.25.
struct Wedge {
  double cx, cy, cz;
  double c, s;
  double grow = 0.0;  // m, every face moved outward by this much (tests probe near-grazing rays with it)
};

struct Sphere {
  double cx, cy, cz;
  double r;
};

// A static vertical cylinder standing on the floor (the shelter task's target): axis (cx, cy), z in [0, h].
struct Cylinder {
  double cx, cy;
  double r, h;
};

// Every occluder of one world. Walls and boxes are OrientedBoxes, agents spheres. An agent's arms, if
// given, are spheres that belong to it: arms[2a] and arms[2a + 1] are agent a's.
struct Occluders {
  std::span<const OrientedBox> walls;
  std::span<const OrientedBox> boxes;
  std::span<const Wedge> ramps;
  std::span<const Sphere> agents;
  std::span<const Sphere> arms = {};
  std::span<const Cylinder> cylinders = {};
};

// The point a line of sight to a ramp aims at, and its vision cone tests: the ramp's centroid, for a
// bounding-box centre (cx, cy, cz) and yaw (c, s). One template for the double reference and the float batch
// path, so both aim at the same point up to rounding.
template <class T>
void ramp_sight_point(T cx, T cy, T cz, T c, T s, T out[3]) {
  out[0] = cx - s * T(kRampCentroidY);
  out[1] = cy + c * T(kRampCentroidY);
  out[2] = cz + T(kRampCentroidZ);
}

// World centres of an agent's two arm spheres, for its centre and yaw (c, s). Double and float alike.
template <class T>
void arm_centres(const T centre[3], T c, T s, T out[2][3]) {
  for (int k = 0; k < 2; ++k) {
    const T lx = T(kArmOffset[k][0]), ly = T(kArmOffset[k][1]);
    out[k][0] = centre[0] + (c * lx - s * ly);
    out[k][1] = centre[1] + (s * lx + c * ly);
    out[k][2] = centre[2] + T(kArmOffset[k][2]);
  }
}

enum class HitKind : uint8_t { kNone, kWall, kBox, kRamp, kAgent, kCylinder };

struct RayHit {
  double t = 0;  // distance along the unit direction, m
  HitKind kind = HitKind::kNone;
  int index = -1;
};

inline constexpr double kNoHit = 1e30;

// Entry distance t >= 0 of the ray origin + t·dir (dir unit) into each shape, or kNoHit.
// A ray starting inside a shape hits it at t = 0.
double ray_box(const double origin[3], const double dir[3], const OrientedBox& box);
double ray_wedge(const double origin[3], const double dir[3], const Wedge& wedge);
double ray_sphere(const double origin[3], const double dir[3], const Sphere& sphere);
double ray_cylinder(const double origin[3], const double dir[3], const Cylinder& cylinder);

// First hit strictly nearer than max_t, skipping agent `skip_agent` (the viewer's own body and arms; -1 for
// none). A hit on an agent's arm reports that agent.
RayHit cast_ray(const Occluders& occ, const double origin[3], const double dir[3], double max_t,
                int skip_agent);

// Facing direction in the plane for a yaw angle: agents face -y at yaw 0 (docs/game.md §1.2, §4.1).
inline void facing_direction(double yaw_c, double yaw_s, double out[2]) {
  out[0] = yaw_s;
  out[1] = -yaw_c;
}

// 2-D cone test: the target lies within kVisionHalfAngle of the facing direction (a target exactly at the
// viewer counts as inside).
bool in_vision_cone(double viewer_x, double viewer_y, double yaw_c, double yaw_s, double target_x,
                    double target_y);

// The point vision aims at: an agent's or a box's centre, a ramp's centroid (ramp_sight_point). Each lies
// inside its solid, at least 0.075 m (an elongated box's half thickness) from its surface.
void sight_point(const Occluders& occ, HitKind kind, int index, double out[3]);

// Line of sight from agent `viewer`'s centre to the target's sight point: the first hit along the 3-D
// segment is the target itself. Target kind is kAgent, kBox or kRamp. The segment ends inside the target,
// so the target is always entered well before its end and the answer never hangs on the segment's length.
bool line_of_sight(const Occluders& occ, int viewer, HitKind target_kind, int target_index);

// Visible = in the cone and in line of sight (docs/game.md §4.1, true centres per §14.7).
bool visible(const Occluders& occ, int viewer, double yaw_c, double yaw_s, HitKind target_kind,
             int target_index);

// 30 world-fixed horizontal rays from agent `agent`'s centre; out[k] = first hit distance, 6 if none or
// farther (§14.6).
void lidar(const Occluders& occ, int agent, std::span<double, kLidarRays> out);

// 3-D distance from a point to an oriented box (0 inside).
double distance_to_box(const double p[3], const OrientedBox& box);
// The cuboid grab and lock measure a ramp's distance to: kRampReachHalf about its bounding-box centre.
OrientedBox ramp_reach_box(const Wedge& wedge);

}  // namespace hns::physics
