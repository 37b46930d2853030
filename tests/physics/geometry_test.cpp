// The scalar vision, line-of-sight and lidar reference on hand-built scenes (docs/game.md §4.1, §4.2, §14.6-7).
#include "physics/geometry.hpp"
#include "physics/sphere_convex.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <vector>

namespace hns::physics {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A 0.5 m high, 0.1 m thick wall along y, centred at x = cx.
OrientedBox wall_x(double cx, double cy = 3.0, double half_len = 1.0, double height = 0.5) {
  return OrientedBox{cx, cy, 0.5 * height, 0.05, half_len, 0.5 * height, 1, 0};
}

TEST(Geometry, RayHitsBoxFaceAtKnownDistance) {
  const OrientedBox box{3.0, 3.0, 0.25, 0.25, 0.25, 0.25, 1, 0};
  const double o[3] = {1.0, 3.0, 0.25}, d[3] = {1, 0, 0};
  EXPECT_NEAR(ray_box(o, d, box), 1.75, 1e-12);
  const double away[3] = {-1, 0, 0};
  EXPECT_GE(ray_box(o, away, box), kNoHit);
  // Rotated by 45°: the corner now points at the ray, 0.25·√2 from the centre.
  const OrientedBox turned{3.0, 3.0, 0.25, 0.25, 0.25, 0.25, std::cos(kPi / 4), std::sin(kPi / 4)};
  EXPECT_NEAR(ray_box(o, d, turned), 2.0 - 0.25 * std::sqrt(2.0), 1e-12);
}

TEST(Geometry, RayHitsRampSlopeOrBackFace) {
  // Yaw 0: back face at y = cy - 0.25 faces -y, slope rises toward -y.
  const Wedge ramp{3.0, 3.0, 0.25, 1, 0};
  // Coming from +y at z = 0.1 (0.15 above the bottom): the slope is at local y = -(z_local) = 0.15.
  const double from_front[3] = {3.0, 5.0, 0.1}, toward_minus_y[3] = {0, -1, 0};
  EXPECT_NEAR(ray_wedge(from_front, toward_minus_y, ramp), 5.0 - (3.0 + 0.15), 1e-12);
  // Coming from -y: the vertical back face at y = 2.75.
  const double from_back[3] = {3.0, 1.0, 0.4}, toward_plus_y[3] = {0, 1, 0};
  EXPECT_NEAR(ray_wedge(from_back, toward_plus_y, ramp), 1.75, 1e-12);
  // Higher up, the slope is hit closer to the back.
  const double high[3] = {3.0, 5.0, 0.2};
  EXPECT_NEAR(ray_wedge(high, toward_minus_y, ramp), 5.0 - (3.0 + 0.05), 1e-12);
  // Above the top edge (z = 0.5): nothing to hit.
  const double above[3] = {3.0, 5.0, 0.55};
  EXPECT_GE(ray_wedge(above, toward_minus_y, ramp), kNoHit);
}

TEST(Geometry, VisionConeIs135Degrees) {
  // An agent at the origin with yaw 0 faces -y.
  auto at_angle_off_facing = [](double deg) {
    const double a = -kPi / 2 + deg * kPi / 180;  // facing direction is -y, i.e. angle -90°
    return std::array<double, 2>{std::cos(a), std::sin(a)};
  };
  for (double deg : {0.0, 30.0, -60.0, 67.0, -67.0}) {
    const auto p = at_angle_off_facing(deg);
    EXPECT_TRUE(in_vision_cone(0, 0, 1, 0, p[0], p[1])) << deg << "°";
  }
  for (double deg : {70.0, -70.0, 90.0, 180.0}) {
    const auto p = at_angle_off_facing(deg);
    EXPECT_FALSE(in_vision_cone(0, 0, 1, 0, p[0], p[1])) << deg << "°";
  }
  // Turning the agent by 90° (yaw π/2) makes it face +x.
  EXPECT_TRUE(in_vision_cone(0, 0, std::cos(kPi / 2), std::sin(kPi / 2), 1, 0));
  EXPECT_FALSE(in_vision_cone(0, 0, std::cos(kPi / 2), std::sin(kPi / 2), 0, -1));
}

TEST(Geometry, WallBetweenAgentsBlocksSight) {
  const std::vector<Sphere> agents = {{1.0, 3.0, 0.15, 0.15}, {5.0, 3.0, 0.15, 0.15}};
  const std::vector<OrientedBox> walls = {wall_x(3.0)};
  const Occluders occ{walls, {}, {}, agents};
  // Agent 0 faces +x (yaw π/2), straight at agent 1.
  EXPECT_FALSE(visible(occ, 0, std::cos(kPi / 2), std::sin(kPi / 2), HitKind::kAgent, 1));
  const Occluders open{{}, {}, {}, agents};
  EXPECT_TRUE(visible(open, 0, std::cos(kPi / 2), std::sin(kPi / 2), HitKind::kAgent, 1));
}

TEST(Geometry, AgentOnBoxSeesOverHalfMetreWall) {
  // The viewer stands on a 0.5 m box (centre at 0.65 m); the target stands on the floor 1.5 m behind the
  // wall. The ray from 0.65 m down to 0.15 m crosses the wall's plane above 0.5 m only if the wall is near
  // the viewer.
  const std::vector<Sphere> agents = {{2.7, 3.0, 0.65, 0.15}, {4.5, 3.0, 0.15, 0.15}};
  const std::vector<OrientedBox> boxes = {{2.7, 3.0, 0.25, 0.25, 0.25, 0.25, 1, 0}};
  const std::vector<OrientedBox> walls = {wall_x(3.0)};
  const Occluders occ{walls, boxes, {}, agents};
  EXPECT_TRUE(line_of_sight(occ, 0, HitKind::kAgent, 1));
  // The same pair with the viewer on the floor: blocked.
  const std::vector<Sphere> on_floor = {{2.7, 3.0, 0.15, 0.15}, {4.5, 3.0, 0.15, 0.15}};
  const Occluders low{walls, {}, {}, on_floor};
  EXPECT_FALSE(line_of_sight(low, 0, HitKind::kAgent, 1));
}

TEST(Geometry, BoxesRampsAndAgentsOccludeButTheFloorDoesNot) {
  const std::vector<Sphere> agents = {{1.0, 3.0, 0.15, 0.15}, {5.0, 3.0, 0.15, 0.15}, {3.0, 3.0, 0.15, 0.15}};
  const Occluders through_agent{{}, {}, {}, agents};
  EXPECT_FALSE(line_of_sight(through_agent, 0, HitKind::kAgent, 1));
  EXPECT_TRUE(line_of_sight(through_agent, 0, HitKind::kAgent, 2));
  const std::vector<Sphere> two = {agents[0], agents[1]};
  const std::vector<OrientedBox> box = {{3.0, 3.0, 0.25, 0.25, 0.25, 0.25, 1, 0}};
  EXPECT_FALSE(line_of_sight(Occluders{{}, box, {}, two}, 0, HitKind::kAgent, 1));
  EXPECT_TRUE(line_of_sight(Occluders{{}, box, {}, two}, 0, HitKind::kBox, 0));
  const std::vector<Wedge> ramp = {{3.0, 3.0, 0.25, 1, 0}};
  EXPECT_FALSE(line_of_sight(Occluders{{}, {}, ramp, two}, 0, HitKind::kAgent, 1));
}

TEST(Geometry, LidarReadsWallDistanceAndRangeCap) {
  const std::vector<Sphere> agents = {{1.0, 3.0, 0.15, 0.15}};
  const std::vector<OrientedBox> walls = {wall_x(3.0, 3.0, 1.0)};
  std::array<double, kLidarRays> out{};
  lidar(Occluders{walls, {}, {}, agents}, 0, out);
  EXPECT_NEAR(out[0], 3.0 - 0.05 - 1.0, 1e-9) << "ray 0 points along +x at the wall";
  EXPECT_DOUBLE_EQ(out[15], kLidarRange) << "ray 15 points along -x at nothing";
  // Ray 1 (12°) hits the same wall plane farther away.
  EXPECT_NEAR(out[1], 1.95 / std::cos(2 * kPi / 30), 1e-9);
  // A wall 7 m away reads as the 6 m range.
  const std::vector<OrientedBox> far = {wall_x(8.05)};
  lidar(Occluders{far, {}, {}, agents}, 0, out);
  EXPECT_DOUBLE_EQ(out[0], kLidarRange);
}

TEST(Geometry, LidarIgnoresOwnBodyButSeesOtherAgents) {
  const std::vector<Sphere> agents = {{1.0, 3.0, 0.15, 0.15}, {2.0, 3.0, 0.15, 0.15}};
  std::array<double, kLidarRays> out{};
  lidar(Occluders{{}, {}, {}, agents}, 0, out);
  EXPECT_NEAR(out[0], 0.85, 1e-9);
  EXPECT_DOUBLE_EQ(out[10], kLidarRange);
}

TEST(Geometry, DistanceToOrientedBox) {
  const OrientedBox box{3.0, 3.0, 0.25, 0.825, 0.075, 0.25, 1, 0};
  const double inside[3] = {3.5, 3.0, 0.2}, beside[3] = {3.0, 3.3, 0.15}, corner[3] = {4.0, 3.2, 0.25};
  EXPECT_DOUBLE_EQ(distance_to_box(inside, box), 0.0);
  EXPECT_NEAR(distance_to_box(beside, box), 0.225, 1e-12);
  EXPECT_NEAR(distance_to_box(corner, box), std::hypot(0.175, 0.125), 1e-12);
  // Turned by 90°, the long side runs along y.
  const OrientedBox turned{3.0, 3.0, 0.25, 0.825, 0.075, 0.25, 0, 1};
  EXPECT_DOUBLE_EQ(distance_to_box(beside, turned), 0.0);
}

// A ramp's sight point is its centroid (0, -1/12, -1/12) in its bounding-box frame, turned with the ramp;
// it lies inside the wedge, (1/6)/√2 from the slope.
TEST(Geometry, RampSightPointIsTheCentroidInsideTheWedge) {
  for (const double yaw : {0.0, 0.7, kPi / 2, -2.0}) {
    const Wedge w{3.0, 2.0, 0.25, std::cos(yaw), std::sin(yaw)};
    double p[3];
    ramp_sight_point(w.cx, w.cy, w.cz, w.c, w.s, p);
    EXPECT_NEAR(std::hypot(p[0] - 3.0, p[1] - 2.0), 1.0 / 12.0, 1e-12);
    EXPECT_NEAR(p[2], 0.25 - 1.0 / 12.0, 1e-12);
    // In the ramp's frame: local y = -1/12 (toward its back face, which is at local -y).
    const double local_y = -w.s * (p[0] - w.cx) + w.c * (p[1] - w.cy);
    EXPECT_NEAR(local_y, -1.0 / 12.0, 1e-12);
    // Rays from far away in every direction toward it enter the wedge at least 0.117 m before it.
    for (int k = 0; k < 16; ++k) {
      const double a = 2 * kPi * k / 16, origin[3] = {p[0] + 3 * std::cos(a), p[1] + 3 * std::sin(a), 0.6};
      double dir[3] = {p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]};
      const double len = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
      for (double& d : dir) d /= len;
      EXPECT_LT(ray_wedge(origin, dir, w), len - 0.117) << "yaw " << yaw << ", direction " << k;
    }
  }
}

// Grab and lock measure a ramp through the cuboid (0.2357, 0.25, 0.3536) about its bounding-box centre.
TEST(Geometry, RampReachBoxIsTheSpecCuboid) {
  const OrientedBox reach = ramp_reach_box(Wedge{3.0, 3.0, 0.25, 0.0, 1.0});  // turned by 90°
  EXPECT_DOUBLE_EQ(reach.hx, 0.2357);
  EXPECT_DOUBLE_EQ(reach.hy, 0.25);
  EXPECT_DOUBLE_EQ(reach.hz, 0.3536);
  const double above[3] = {3.0, 3.0, 0.25 + 0.3536 + 0.1}, beside[3] = {3.0, 3.0 + 0.2357 + 0.1, 0.25};
  EXPECT_NEAR(distance_to_box(above, reach), 0.1, 1e-12);
  EXPECT_NEAR(distance_to_box(beside, reach), 0.1, 1e-12) << "the ramp's x axis points along world y";
}

// Arms are part of their agent: a ray through an arm reports the agent; the caster's own arms are skipped.
TEST(Geometry, ArmsBelongToTheirAgent) {
  const double centre[3] = {3.0, 3.0, 0.15};
  double arm[2][3];
  arm_centres(centre, 1.0, 0.0, arm);  // yaw 0: arms at (2.87, 2.925, 0.10) and (3.13, 2.925, 0.10)
  EXPECT_NEAR(arm[0][0], 2.87, 1e-12);
  EXPECT_NEAR(arm[1][0], 3.13, 1e-12);
  EXPECT_NEAR(arm[0][1], 2.925, 1e-12);
  EXPECT_NEAR(arm[0][2], 0.10, 1e-12);
  const std::vector<Sphere> agents = {{3.0, 3.0, 0.15, 0.15}, {1.0, 2.925, 0.10, 0.15}};
  const std::vector<Sphere> arms = {
      {arm[0][0], arm[0][1], arm[0][2], kArmRadius}, {arm[1][0], arm[1][1], arm[1][2], kArmRadius}, {}, {}};
  const Occluders occ{{}, {}, {}, agents, arms};
  // Along +x at the arms' height and row, from beyond the right arm back toward the agent: the right arm
  // (x 3.13 + 0.05) is the first thing hit.
  const double origin[3] = {4.0, 2.925, 0.10}, west[3] = {-1.0, 0.0, 0.0};
  RayHit hit = cast_ray(occ, origin, west, 10.0, 1);
  EXPECT_EQ(hit.kind, HitKind::kAgent);
  EXPECT_EQ(hit.index, 0);
  EXPECT_NEAR(hit.t, 4.0 - 3.18, 1e-9);
  hit = cast_ray(occ, origin, west, 10.0, 0);
  EXPECT_EQ(hit.index, 1) << "with agent 0 skipped, its arms are skipped too";
}

// A wedge grown by g has every face moved out by g, the slope included.
TEST(Geometry, GrownWedgeMovesEveryFace) {
  Wedge w{0.0, 0.0, 0.0, 1.0, 0.0};
  const double down[3] = {0, 0, -1};
  const double above_slope[3] = {0.0, 0.1, 1.0};  // the slope y + z = 0 lies at z = -0.1 here
  EXPECT_NEAR(ray_wedge(above_slope, down, w), 1.1, 1e-12);
  w.grow = 0.01;
  EXPECT_NEAR(ray_wedge(above_slope, down, w), 1.1 - 0.01 * std::sqrt(2.0), 1e-12);
  const double beside[3] = {0.255, -0.2, -0.2}, west[3] = {-1, 0, 0};
  EXPECT_NEAR(ray_wedge(beside, west, w), 0.0, 1e-12) << "the cap at x = 0.26 now holds the origin";
}

}  // namespace
}  // namespace hns::physics

namespace hns::physics {

// The exact sphere-convex contact (sphere_convex.hpp) on a unit cube: the depth is the radius less the true
// distance to the surface (for a box, the clamped point), and the normal points from the
// surface's closest point to the centre, including where that point is on an edge or a corner, where ODE's
// collider got the normal wrong.
TEST(SphereConvex, DepthAndNormalMatchTheClosestSurfacePoint) {
  const double planes[24] = {1, 0,  0, 0.5, -1, 0, 0, 0.5, 0, 1, 0,  0.5,
                             0, -1, 0, 0.5, 0,  0, 1, 0.5, 0, 0, -1, 0.5};
  std::vector<double> points;
  for (int i = 0; i < 8; ++i) {
    points.insert(points.end(), {i & 1 ? 0.5 : -0.5, i & 2 ? 0.5 : -0.5, i & 4 ? 0.5 : -0.5});
  }
  const int edges[24] = {0, 1, 2, 3, 4, 5, 6, 7, 0, 2, 1, 3, 4, 6, 5, 7, 0, 4, 1, 5, 2, 6, 3, 7};
  const ConvexShape cube{planes, points, edges};
  const double pos[3] = {10, 20, 0.5};
  const double c = std::cos(0.3), s = std::sin(0.3);
  const double rot[12] = {c, -s, 0, 0, s, c, 0, 0, 0, 0, 1, 0};  // yaw 0.3
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.8, 0.8);
  int outside = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const double local[3] = {u(rng), u(rng), u(rng)};
    const bool inside = std::abs(local[0]) < 0.5 && std::abs(local[1]) < 0.5 && std::abs(local[2]) < 0.5;
    if (inside) continue;
    ++outside;
    // The closest surface point by clamping (exact for a box), then the world centre.
    double q[3];
    for (int k = 0; k < 3; ++k) q[k] = std::clamp(local[k], -0.5, 0.5);
    const double dist = std::hypot(local[0] - q[0], local[1] - q[1], local[2] - q[2]);
    const double centre[3] = {pos[0] + c * local[0] - s * local[1], pos[1] + s * local[0] + c * local[1],
                              pos[2] + local[2]};
    SphereContact contact;
    const double radius = 0.4;
    const bool hit = collide_sphere_convex(centre, radius, pos, rot, cube, contact);
    ASSERT_EQ(hit, dist < radius) << "trial " << trial;
    if (!hit) continue;
    EXPECT_NEAR(contact.depth, radius - dist, 1e-12);
    const double n_local[3] = {(local[0] - q[0]) / dist, (local[1] - q[1]) / dist, (local[2] - q[2]) / dist};
    EXPECT_NEAR(contact.normal[0], c * n_local[0] - s * n_local[1], 1e-9);
    EXPECT_NEAR(contact.normal[1], s * n_local[0] + c * n_local[1], 1e-9);
    EXPECT_NEAR(contact.normal[2], n_local[2], 1e-9);
  }
  EXPECT_GT(outside, 100);
  // A centre inside: out through the nearest face (+x here), as deep as the radius plus the way to it.
  const double inside_local[3] = {0.3, 0.1, -0.05};
  const double centre[3] = {pos[0] + c * inside_local[0] - s * inside_local[1],
                            pos[1] + s * inside_local[0] + c * inside_local[1], pos[2] + inside_local[2]};
  SphereContact contact;
  ASSERT_TRUE(collide_sphere_convex(centre, 0.1, pos, rot, cube, contact));
  EXPECT_NEAR(contact.depth, 0.1 + 0.2, 1e-12);
  EXPECT_NEAR(contact.normal[0], c, 1e-12);
  EXPECT_NEAR(contact.normal[1], s, 1e-12);
  EXPECT_NEAR(contact.normal[2], 0.0, 1e-12);
}

}  // namespace hns::physics
