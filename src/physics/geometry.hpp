// Scalar geometry of the game world: ray casts against walls, boxes, ramps and agents, the vision cone,
// line of sight, lidar and point-to-cuboid distance (SPEC.md §3.3, §4.1, §4.2, §14.6, §14.7).
// These are the reference implementations; the batch layer's SIMD kernels are tested against them.
#pragma once

#include <cstdint>
#include <span>

namespace hns::physics {

inline constexpr double kVisionHalfAngle = 3.0 * 3.14159265358979323846 / 8.0;  // rad, 135° cone
inline constexpr int kLidarRays = 30;       // world-fixed, angle 2πk/30 from +x
inline constexpr double kLidarRange = 6.0;  // m; no hit or a farther hit reads 6 (§14.6)
inline constexpr double kRampHalf = 0.25;   // m, half extent of the ramp's bounding box

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
};

struct Sphere {
  double cx, cy, cz;
  double r;
};

// Every occluder of one world. Walls and boxes are OrientedBoxes, agents spheres.
struct Occluders {
  std::span<const OrientedBox> walls;
  std::span<const OrientedBox> boxes;
  std::span<const Wedge> ramps;
  std::span<const Sphere> agents;
};

enum class HitKind : uint8_t { kNone, kWall, kBox, kRamp, kAgent };

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

// First hit within max_t, skipping agent `skip_agent` (the viewer's own body; -1 for none).
RayHit cast_ray(const Occluders& occ, const double origin[3], const double dir[3], double max_t,
                int skip_agent);

// Facing direction in the plane for a yaw angle: agents face -y at yaw 0 (SPEC §1.2, §4.1).
inline void facing_direction(double yaw_c, double yaw_s, double out[2]) {
  out[0] = yaw_s;
  out[1] = -yaw_c;
}

// 2-D cone test: the target lies within kVisionHalfAngle of the facing direction (a target exactly at the
// viewer counts as inside).
bool in_vision_cone(double viewer_x, double viewer_y, double yaw_c, double yaw_s, double target_x,
                    double target_y);

// Line of sight from agent `viewer`'s centre to the centre of the target: the first hit along the 3-D
// segment is the target itself. Target kind is kAgent, kBox or kRamp.
bool line_of_sight(const Occluders& occ, int viewer, HitKind target_kind, int target_index);

// Visible = in the cone and in line of sight (SPEC §4.1, true centres per §14.7).
bool visible(const Occluders& occ, int viewer, double yaw_c, double yaw_s, HitKind target_kind,
             int target_index);

// 30 world-fixed horizontal rays from agent `agent`'s centre; out[k] = first hit distance, 6 if none or
// farther (§14.6).
void lidar(const Occluders& occ, int agent, std::span<double, kLidarRays> out);

// 3-D distance from a point to an oriented box (0 inside). For ramps the bounding box is used.
double distance_to_box(const double p[3], const OrientedBox& box);
OrientedBox wedge_bounds(const Wedge& wedge);

}  // namespace hns::physics
