#include "batch/ray_kernels.hpp"

#include <xsimd/xsimd.hpp>

#include <algorithm>
#include <cmath>

namespace hns::batch {
namespace {

constexpr float kRampHalf = 0.25f;  // m, half extent of the ramp's bounding box

// The same arithmetic, written once for a float (one ray) and once for an xsimd batch (W rays): operators and
// these helpers are overloaded for both, so the vector and scalar paths round identically (the build turns
// FMA contraction off). min/max return their second argument on NaN in both.
template <class F>
struct Ops {
  using B = xsimd::batch_bool<float>;
  static F select(B c, F a, F b) { return xsimd::select(c, a, b); }
  static F min(F a, F b) { return xsimd::min(a, b); }
  static F max(F a, F b) { return xsimd::max(a, b); }
  static F sqrt(F a) { return xsimd::sqrt(a); }
  static F load(const float* p) { return F::load_unaligned(p); }
  static bool all(B b) { return xsimd::all(b); }
};
template <>
struct Ops<float> {
  using B = bool;
  static float select(bool c, float a, float b) { return c ? a : b; }
  static float min(float a, float b) { return a < b ? a : b; }
  static float max(float a, float b) { return a > b ? a : b; }
  static float sqrt(float a) { return std::sqrt(a); }
  static float load(const float* p) { return *p; }
  static bool all(bool b) { return b; }
};

// One block of a fan's rays (one ray for F = float): directions, their reciprocals and lengths. Yaw leaves z
// alone, so 1/dz serves every shape; 1/dx and 1/dy serve every shape that is not rotated (the walls).
template <class F>
struct RayBlock {
  F dx, dy, dz, inv_dx, inv_dy, inv_dz, max_t;
  RayBlock(const RayFan& fan, int i)
      : dx(Ops<F>::load(fan.dx + i)),
        dy(Ops<F>::load(fan.dy + i)),
        dz(Ops<F>::load(fan.dz + i)),
        inv_dx(F(1.0f) / dx),
        inv_dy(F(1.0f) / dy),
        inv_dz(F(1.0f) / dz),
        max_t(Ops<F>::load(fan.max_t + i)) {}
};

// The parametric interval [t0, t1] of the ray still inside the shape, or empty.
template <class F>
struct Interval {
  using B = typename Ops<F>::B;
  F t0, t1;
  B empty;
  explicit Interval(F max_t) : t0(0.0f), t1(max_t), empty(F(0.0f) > max_t) {}

  // Keeps the part with n·p <= d along a ray whose direction has n·dir = den (inv = 1/den), where
  // num = d - n·origin is the same for every ray (a scalar per shape).
  void clip(float num, F den, F inv) {
    using O = Ops<F>;
    const F zero(0.0f);
    const F r = F(num) * inv;  // where the ray crosses the plane; unused when den == 0
    t0 = O::select(den < zero, O::max(t0, r), t0);
    t1 = O::select(den > zero, O::min(t1, r), t1);
    if (num < 0.0f) empty = empty | (den == zero);  // parallel to the plane and outside it
  }
  // Keeps the slab |x| <= h, origin at x = o: the two planes of one axis share a reciprocal.
  void slab(float h, float o, F d, F inv) {
    clip(h - o, d, inv);
    clip(h + o, F(0.0f) - d, F(0.0f) - inv);
  }
  // Entry distance, or kNoHitT for an empty interval.
  F entry() const { return Ops<F>::select(empty | (t0 > t1), F(kNoHitT), t0); }
};

// The fan's origin in a shape's yaw frame centred at (cx, cy, cz): scalars, shared by every ray.
struct LocalOrigin {
  float x, y, z;
  LocalOrigin(const RayFan& fan, float cx, float cy, float cz, float c, float s) {
    const float px = fan.ox - cx, py = fan.oy - cy;
    x = c * px + s * py;
    y = c * py - s * px;
    z = fan.oz - cz;
  }
};

// Entry distance into a yaw-rotated box, or kNoHitT.
template <class F>
F ray_box(const RayFan& fan, const RayBlock<F>& r, float cx, float cy, float cz, float hx, float hy, float hz,
          float c, float s) {
  const LocalOrigin o(fan, cx, cy, cz, c, s);
  Interval<F> in(r.max_t);
  if (c == 1.0f && s == 0.0f) {
    // Axis-aligned (every wall): the direction is the world one, exactly as the rotation below would give.
    in.slab(hx, o.x, r.dx, r.inv_dx);
    in.slab(hy, o.y, r.dy, r.inv_dy);
  } else {
    const F dx = F(c) * r.dx + F(s) * r.dy, dy = F(c) * r.dy - F(s) * r.dx;
    in.slab(hx, o.x, dx, F(1.0f) / dx);
    in.slab(hy, o.y, dy, F(1.0f) / dy);
  }
  in.slab(hz, o.z, r.dz, r.inv_dz);
  return in.entry();
}

// Entry distance into a ramp wedge (local: |x| <= h, y >= -h, z >= -h, y + z <= 0), or kNoHitT.
template <class F>
F ray_wedge(const RayFan& fan, const RayBlock<F>& r, float cx, float cy, float cz, float c, float s) {
  const float h = kRampHalf;
  const LocalOrigin o(fan, cx, cy, cz, c, s);
  const F dx = F(c) * r.dx + F(s) * r.dy, dy = F(c) * r.dy - F(s) * r.dx;
  const F inv_dy = F(1.0f) / dy;
  const F slope = dy + r.dz;
  Interval<F> in(r.max_t);
  in.slab(h, o.x, dx, F(1.0f) / dx);
  in.clip(h + o.y, F(0.0f) - dy, F(0.0f) - inv_dy);
  in.clip(h + o.z, F(0.0f) - r.dz, F(0.0f) - r.inv_dz);
  in.clip(0.0f - (o.y + o.z), slope, F(1.0f) / slope);
  return in.entry();
}

// Entry distance into a vertical cylinder standing on the floor (axis (cx, cy), z in [0, h]), or kNoHitT: its
// side at the smaller root of |p + t d|² = r² in the plane, within the height, or its top cap from above.
template <class F>
F ray_cylinder(const RayFan& fan, const RayBlock<F>& r, float cx, float cy, float radius, float h) {
  using O = Ops<F>;
  const float px = fan.ox - cx, py = fan.oy - cy, oz = fan.oz;
  const float c = px * px + py * py - radius * radius;
  if (c <= 0.0f && oz >= 0.0f && oz <= h) return F(0.0f);  // the origin inside
  const F zero(0.0f);
  const F a = r.dx * r.dx + r.dy * r.dy, b = F(px) * r.dx + F(py) * r.dy;
  const F disc = b * b - a * F(c);
  const F side = (F(0.0f) - b - O::sqrt(O::max(disc, zero))) / a;
  const F z = F(oz) + side * r.dz;
  const auto side_hit = (a > zero) & (disc >= zero) & (side >= zero) & (z >= zero) & (z <= F(h));
  F best = O::select(side_hit, side, F(kNoHitT));
  if (oz > h) {
    const F top = F(h - oz) * r.inv_dz;
    const F x = F(px) + top * r.dx, y = F(py) + top * r.dy;
    const auto top_hit = (r.dz < zero) & (x * x + y * y <= F(radius * radius));
    best = O::min(best, O::select(top_hit, top, F(kNoHitT)));
  }
  return O::select(best <= r.max_t, best, F(kNoHitT));
}

// How the rays pass a point (a sphere's centre): m = origin - point (the same for every ray), b = m·d per ray
// (negative while the point is ahead).
template <class F>
struct Approach {
  float mx, my, mz, m2;
  F b;
  Approach(const RayFan& fan, const RayBlock<F>& r, float cx, float cy, float cz)
      : mx(fan.ox - cx), my(fan.oy - cy), mz(fan.oz - cz), m2(mx * mx + my * my + mz * mz) {
    b = F(mx) * r.dx + F(my) * r.dy + F(mz) * r.dz;
  }
  // Every ray misses the ball of this radius about the point (the origin outside it): the ball lies behind
  // the ray, off its line (b² < |m|² - radius²), or past its end (no point of it nearer than -b - radius).
  bool all_miss(float radius, F max_t) const {
    const F zero(0.0f);
    const F off_line = b * b - F(m2 - radius * radius);
    return m2 > radius * radius &&
           Ops<F>::all((b > zero) | (off_line < zero) | (zero - b - F(radius) > max_t));
  }
};

// Entry distance into a sphere of `radius` about the approach's point (0 from inside), or kNoHitT, for a
// discriminant disc (negative: the line misses).
template <class F>
F sphere_entry(const Approach<F>& a, const RayBlock<F>& r, float radius, F disc) {
  using O = Ops<F>;
  if (a.m2 <= radius * radius) return F(0.0f);  // the origin is inside
  const F zero(0.0f);
  const F t = zero - a.b - O::sqrt(O::max(disc, zero));
  const auto miss = (a.b > zero) | (disc < zero) | (t > r.max_t);
  return O::select(miss, F(kNoHitT), t);
}

// A body sphere: disc = b² - (|m|² - r²), cheap, with a rounding error that grows with |m|² (about 1e-5 m²
// at 8 m): the rays that graze a body sphere are rare and fall in the grazing band.
template <class F>
F body_sphere_entry(const Approach<F>& a, const RayBlock<F>& r, float radius) {
  return sphere_entry(a, r, radius, a.b * a.b - F(a.m2 - radius * radius));
}

// An arm: disc = r² - |q|², q = m - b·d the centre's offset from the ray's line, which does not cancel for
// a far sphere. It must not: an arm's top lies exactly at its agent's centre height, where the lidar rays of
// an agent on the same floor run, so those rays graze it all the time; this decides them to about 1e-6 m,
// the cheap form to 1e-3 m.
template <class F>
F arm_sphere_entry(const Approach<F>& a, const RayBlock<F>& r, float radius) {
  const F qx = F(a.mx) - a.b * r.dx, qy = F(a.my) - a.b * r.dy, qz = F(a.mz) - a.b * r.dz;
  return sphere_entry(a, r, radius, F(radius * radius) - (qx * qx + qy * qy + qz * qz));
}

// The nearest hit per lane so far; ids kept as floats (exact below 2^24) so one select moves both.
template <class F>
struct Nearest {
  F t = F(kNoHitT), id = F(-1.0f);
  void keep(F t_shape, int shape) {
    const auto nearer = t_shape < t;  // strict: on a tie the earlier (lower) id stays
    t = Ops<F>::select(nearer, t_shape, t);
    id = Ops<F>::select(nearer, F(float(shape)), id);
  }
};

// Rays [i, i + lanes of F) of the fan against every live shape, in id order.
template <class F>
Nearest<F> cast_block(const ShapesView& s, const RayFan& fan, int i) {
  const RayBlock<F> r(fan, i);
  Nearest<F> best;
  for (int k = 0; k < s.live_boxes; ++k) {
    if (k == fan.skip_id) continue;
    best.keep(ray_box(fan, r, s.box_cx[k], s.box_cy[k], s.box_cz[k], s.box_hx[k], s.box_hy[k], s.box_hz[k],
                      s.box_c[k], s.box_s[k]),
              k);
  }
  for (int k = 0; k < s.live_wedges; ++k) {
    if (s.wedge_id(k) == fan.skip_id) continue;
    best.keep(ray_wedge(fan, r, s.wedge_cx[k], s.wedge_cy[k], s.wedge_cz[k], s.wedge_c[k], s.wedge_s[k]),
              s.wedge_id(k));
  }
  const int per = s.spheres_per_body;
  for (int body = 0; body * per < s.live_spheres; ++body) {
    const int id = s.sphere_id(body);
    if (id == fan.skip_id) continue;
    const int first = body * per;
    const Approach<F> centre(fan, r, s.sphere_cx[first], s.sphere_cy[first], s.sphere_cz[first]);
    best.keep(body_sphere_entry(centre, r, s.sphere_r[first]), id);
    if (per == 1 || (s.body_reach > 0.0f && centre.all_miss(s.body_reach, r.max_t))) continue;
    for (int k = first + 1; k < first + per && k < s.live_spheres; ++k) {
      const Approach<F> part(fan, r, s.sphere_cx[k], s.sphere_cy[k], s.sphere_cz[k]);
      best.keep(arm_sphere_entry(part, r, s.sphere_r[k]), id);
    }
  }
  for (int k = 0; k < s.live_cylinders; ++k) {
    if (s.cylinder_id(k) == fan.skip_id) continue;
    best.keep(ray_cylinder(fan, r, s.cyl_cx[k], s.cyl_cy[k], s.cyl_r[k], s.cyl_h[k]), s.cylinder_id(k));
  }
  return best;
}

}  // namespace

int ray_simd_width() {
  return int(xsimd::batch<float>::size);
}

void first_hits_scalar(const ShapesView& shapes, const RayFan& fan, float* t, int32_t* id) {
  for (int i = 0; i < fan.count; ++i) {
    const Nearest<float> best = cast_block<float>(shapes, fan, i);
    t[i] = best.t;
    id[i] = int32_t(best.id);
  }
}

void first_hits(const ShapesView& shapes, const RayFan& fan, float* t, int32_t* id) {
  using F = xsimd::batch<float>;
  constexpr int W = int(F::size);
  alignas(64) float lane_id[W];
  // Whole blocks straight from the caller's arrays.
  int i = 0;
  for (; i + W <= fan.count; i += W) {
    const Nearest<F> best = cast_block<F>(shapes, fan, i);
    best.t.store_unaligned(t + i);
    best.id.store_aligned(lane_id);
    for (int l = 0; l < W; ++l) id[i + l] = int32_t(lane_id[l]);
  }
  if (i == fan.count) return;
  // The tail: copied into a full block whose spare lanes are zero-length rays along +x, results dropped.
  alignas(64) float dx[W], dy[W], dz[W], max_t[W], lane_t[W];
  const int n = fan.count - i;
  for (int l = 0; l < W; ++l) {
    const bool real = l < n;
    dx[l] = real ? fan.dx[i + l] : 1.0f;
    dy[l] = real ? fan.dy[i + l] : 0.0f;
    dz[l] = real ? fan.dz[i + l] : 0.0f;
    max_t[l] = real ? fan.max_t[i + l] : 0.0f;
  }
  RayFan tail = fan;
  tail.dx = dx, tail.dy = dy, tail.dz = dz, tail.max_t = max_t, tail.count = W;
  const Nearest<F> best = cast_block<F>(shapes, tail, 0);
  best.t.store_aligned(lane_t);
  best.id.store_aligned(lane_id);
  for (int l = 0; l < n; ++l) {
    t[i + l] = lane_t[l];
    id[i + l] = int32_t(lane_id[l]);
  }
}

}  // namespace hns::batch
