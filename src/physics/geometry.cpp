#include "physics/geometry.hpp"

#include <algorithm>
#include <cmath>

namespace hns::physics {
namespace {

// Slab clip of a ray against the planes n·p <= d in a local frame, keeping [t0, t1]. Returns false if empty.
bool clip(double n_dot_o_minus_d, double n_dot_dir, double& t0, double& t1) {
  if (std::abs(n_dot_dir) < 1e-15) return n_dot_o_minus_d <= 0;
  const double t = -n_dot_o_minus_d / n_dot_dir;
  if (n_dot_dir < 0) {
    t0 = std::max(t0, t);
  } else {
    t1 = std::min(t1, t);
  }
  return t0 <= t1;
}

// World point/direction into a yaw frame centred at (cx, cy, cz).
void to_local(const double p[3], double cx, double cy, double cz, double c, double s, double out[3]) {
  const double dx = p[0] - cx, dy = p[1] - cy;
  out[0] = c * dx + s * dy;
  out[1] = -s * dx + c * dy;
  out[2] = p[2] - cz;
}
void dir_to_local(const double d[3], double c, double s, double out[3]) {
  out[0] = c * d[0] + s * d[1];
  out[1] = -s * d[0] + c * d[1];
  out[2] = d[2];
}

}  // namespace

double ray_box(const double origin[3], const double dir[3], const OrientedBox& box) {
  double o[3], d[3];
  to_local(origin, box.cx, box.cy, box.cz, box.c, box.s, o);
  dir_to_local(dir, box.c, box.s, d);
  const double h[3] = {box.hx, box.hy, box.hz};
  double t0 = 0, t1 = kNoHit;
  for (int a = 0; a < 3; ++a) {
    if (!clip(o[a] - h[a], d[a], t0, t1)) return kNoHit;    // +axis face
    if (!clip(-o[a] - h[a], -d[a], t0, t1)) return kNoHit;  // -axis face
  }
  return t0;
}

double ray_wedge(const double origin[3], const double dir[3], const Wedge& w) {
  double o[3], d[3];
  to_local(origin, w.cx, w.cy, w.cz, w.c, w.s, o);
  dir_to_local(dir, w.c, w.s, d);
  const double h = kRampHalf + w.grow;
  const double slope = w.grow * std::sqrt(2.0);  // the slope plane y + z <= 0 moved out by `grow`
  double t0 = 0, t1 = kNoHit;
  if (!clip(o[0] - h, d[0], t0, t1) || !clip(-o[0] - h, -d[0], t0, t1)) return kNoHit;
  if (!clip(-o[1] - h, -d[1], t0, t1) || !clip(-o[2] - h, -d[2], t0, t1)) return kNoHit;
  if (!clip(o[1] + o[2] - slope, d[1] + d[2], t0, t1)) return kNoHit;  // slope y + z <= 0
  return t0;
}

double ray_sphere(const double origin[3], const double dir[3], const Sphere& sp) {
  const double m[3] = {origin[0] - sp.cx, origin[1] - sp.cy, origin[2] - sp.cz};
  const double b = m[0] * dir[0] + m[1] * dir[1] + m[2] * dir[2];
  if (m[0] * m[0] + m[1] * m[1] + m[2] * m[2] <= sp.r * sp.r) return 0;  // origin inside
  if (b > 0) return kNoHit;
  // r² - |q|², q = the centre's offset from the ray's closest point: no cancellation for far spheres.
  const double q[3] = {m[0] - b * dir[0], m[1] - b * dir[1], m[2] - b * dir[2]};
  const double disc = sp.r * sp.r - (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
  if (disc < 0) return kNoHit;
  return -b - std::sqrt(disc);
}

double ray_cylinder(const double origin[3], const double dir[3], const Cylinder& cyl) {
  const double px = origin[0] - cyl.cx, py = origin[1] - cyl.cy, oz = origin[2];
  const double c = px * px + py * py - cyl.r * cyl.r;
  if (c <= 0 && oz >= 0 && oz <= cyl.h) return 0;  // origin inside
  double best = kNoHit;
  // The side: |p + t d|² = r² in the plane, entered at the smaller root, within the height.
  const double a = dir[0] * dir[0] + dir[1] * dir[1], b = px * dir[0] + py * dir[1];
  const double disc = b * b - a * c;
  if (a > 0 && disc >= 0) {
    const double t = (-b - std::sqrt(disc)) / a;
    const double z = oz + t * dir[2];
    if (t >= 0 && z >= 0 && z <= cyl.h) best = t;
  }
  // The top cap, from above.
  if (dir[2] < 0 && oz > cyl.h) {
    const double t = (cyl.h - oz) / dir[2];
    const double x = px + t * dir[0], y = py + t * dir[1];
    if (x * x + y * y <= cyl.r * cyl.r) best = std::min(best, t);
  }
  return best;
}

RayHit cast_ray(const Occluders& occ, const double origin[3], const double dir[3], double max_t,
                int skip_agent) {
  RayHit hit;
  hit.t = max_t;
  auto consider = [&](double t, HitKind kind, int index) {
    if (t < hit.t) {
      hit.t = t;
      hit.kind = kind;
      hit.index = index;
    }
  };
  for (size_t i = 0; i < occ.walls.size(); ++i)
    consider(ray_box(origin, dir, occ.walls[i]), HitKind::kWall, int(i));
  for (size_t i = 0; i < occ.boxes.size(); ++i)
    consider(ray_box(origin, dir, occ.boxes[i]), HitKind::kBox, int(i));
  for (size_t i = 0; i < occ.ramps.size(); ++i)
    consider(ray_wedge(origin, dir, occ.ramps[i]), HitKind::kRamp, int(i));
  for (size_t i = 0; i < occ.agents.size(); ++i) {
    if (int(i) != skip_agent) consider(ray_sphere(origin, dir, occ.agents[i]), HitKind::kAgent, int(i));
  }
  for (size_t i = 0; i < occ.arms.size(); ++i) {
    const int agent = int(i / 2);
    if (agent != skip_agent) consider(ray_sphere(origin, dir, occ.arms[i]), HitKind::kAgent, agent);
  }
  for (size_t i = 0; i < occ.cylinders.size(); ++i)
    consider(ray_cylinder(origin, dir, occ.cylinders[i]), HitKind::kCylinder, int(i));
  return hit;
}

bool in_vision_cone(double vx, double vy, double yaw_c, double yaw_s, double tx, double ty) {
  const double dx = tx - vx, dy = ty - vy;
  const double len = std::sqrt(dx * dx + dy * dy);
  if (len == 0) return true;
  double f[2];
  facing_direction(yaw_c, yaw_s, f);
  const double cos_angle = (dx * f[0] + dy * f[1]) / len;
  return cos_angle >= std::cos(kVisionHalfAngle);
}

void sight_point(const Occluders& occ, HitKind kind, int index, double out[3]) {
  switch (kind) {
    case HitKind::kAgent: {
      const Sphere& a = occ.agents[index];
      out[0] = a.cx, out[1] = a.cy, out[2] = a.cz;
      break;
    }
    case HitKind::kBox: {
      const OrientedBox& b = occ.boxes[index];
      out[0] = b.cx, out[1] = b.cy, out[2] = b.cz;
      break;
    }
    default: {
      const Wedge& r = occ.ramps[index];
      ramp_sight_point(r.cx, r.cy, r.cz, r.c, r.s, out);
      break;
    }
  }
}

bool line_of_sight(const Occluders& occ, int viewer, HitKind target_kind, int target_index) {
  const Sphere& v = occ.agents[viewer];
  const double origin[3] = {v.cx, v.cy, v.cz};
  double target[3];
  sight_point(occ, target_kind, target_index, target);
  double dir[3] = {target[0] - origin[0], target[1] - origin[1], target[2] - origin[2]};
  const double len = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
  if (len < 1e-12) return true;
  for (double& x : dir) x /= len;
  // The segment ends inside the target, so the target is hit before its end, with room to spare.
  const RayHit hit = cast_ray(occ, origin, dir, len, viewer);
  return hit.kind == target_kind && hit.index == target_index;
}

bool visible(const Occluders& occ, int viewer, double yaw_c, double yaw_s, HitKind target_kind,
             int target_index) {
  const Sphere& v = occ.agents[viewer];
  double target[3];
  sight_point(occ, target_kind, target_index, target);
  if (target_kind == HitKind::kAgent && target_index == viewer) return true;
  return in_vision_cone(v.cx, v.cy, yaw_c, yaw_s, target[0], target[1]) &&
         line_of_sight(occ, viewer, target_kind, target_index);
}

void lidar(const Occluders& occ, int agent, std::span<double, kLidarRays> out) {
  const Sphere& a = occ.agents[agent];
  const double origin[3] = {a.cx, a.cy, a.cz};
  for (int k = 0; k < kLidarRays; ++k) {
    const double angle = 2.0 * 3.14159265358979323846 * k / kLidarRays;
    const double dir[3] = {std::cos(angle), std::sin(angle), 0.0};
    out[k] = cast_ray(occ, origin, dir, kLidarRange, agent).t;
  }
}

double distance_to_box(const double p[3], const OrientedBox& box) {
  double q[3];
  to_local(p, box.cx, box.cy, box.cz, box.c, box.s, q);
  const double h[3] = {box.hx, box.hy, box.hz};
  double sq = 0;
  for (int a = 0; a < 3; ++a) {
    const double excess = std::abs(q[a]) - h[a];
    if (excess > 0) sq += excess * excess;
  }
  return std::sqrt(sq);
}

OrientedBox ramp_reach_box(const Wedge& w) {
  return OrientedBox{w.cx, w.cy, w.cz, kRampReachHalf[0], kRampReachHalf[1], kRampReachHalf[2], w.c, w.s};
}

}  // namespace hns::physics
