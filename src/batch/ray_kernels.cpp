#include "batch/ray_kernels.hpp"

#include <xsimd/xsimd.hpp>

#include <algorithm>
#include <cmath>

namespace hns::batch {
namespace {

constexpr float kRampHalf = 0.25f;  // m, half extent of the ramp's bounding box

// The same arithmetic, written once for a float and once for an xsimd batch (operators and min/max/select
// are overloaded for both), so the vector and scalar paths agree bit for bit.
template <class F, class B>
struct Ops {
  static F select(B c, F a, F b) { return xsimd::select(c, a, b); }
  static F min(F a, F b) { return xsimd::min(a, b); }
  static F max(F a, F b) { return xsimd::max(a, b); }
  static F sqrt(F a) { return xsimd::sqrt(a); }
};
template <>
struct Ops<float, bool> {
  static float select(bool c, float a, float b) { return c ? a : b; }
  static float min(float a, float b) { return a < b ? a : b; }
  static float max(float a, float b) { return a > b ? a : b; }
  static float sqrt(float a) { return std::sqrt(a); }
};

// Clips [t0, t1] by the half-space n·p <= d along the ray (num = d - n·o, den = n·dir).
template <class F, class B>
void clip(F num, F den, F& t0, F& t1, B& empty) {
  using O = Ops<F, B>;
  const F zero(0.0f);
  const F r = num / den;
  t0 = O::select(den < zero, O::max(t0, r), t0);
  t1 = O::select(den > zero, O::min(t1, r), t1);
  empty = empty | ((den == zero) & (num < zero));
}

// The ray's origin and direction in a shape's yaw frame centred at (cx, cy, cz).
template <class F>
struct LocalRay {
  F ox, oy, oz, dx, dy, dz;
  LocalRay(const Ray& ray, F cx, F cy, F cz, F c, F s) {
    const F px = F(ray.ox) - cx, py = F(ray.oy) - cy;
    oz = F(ray.oz) - cz;
    ox = c * px + s * py;
    oy = c * py - s * px;
    dx = c * F(ray.dx) + s * F(ray.dy);
    dy = c * F(ray.dy) - s * F(ray.dx);
    dz = F(ray.dz);
  }
};

// Entry distance into a yaw-rotated box, or kNoHitT.
template <class F, class B>
F ray_box(const Ray& ray, F cx, F cy, F cz, F hx, F hy, F hz, F c, F s) {
  using O = Ops<F, B>;
  const LocalRay<F> l(ray, cx, cy, cz, c, s);
  const F ox = l.ox, oy = l.oy, oz = l.oz, dx = l.dx, dy = l.dy, dz = l.dz;
  F t0(0.0f), t1(ray.max_t);
  B empty = t0 > t1;
  clip<F, B>(hx - ox, dx, t0, t1, empty);
  clip<F, B>(hx + ox, F(0.0f) - dx, t0, t1, empty);
  clip<F, B>(hy - oy, dy, t0, t1, empty);
  clip<F, B>(hy + oy, F(0.0f) - dy, t0, t1, empty);
  clip<F, B>(hz - oz, dz, t0, t1, empty);
  clip<F, B>(hz + oz, F(0.0f) - dz, t0, t1, empty);
  return O::select(empty | (t0 > t1), F(kNoHitT), t0);
}

// Entry distance into a ramp wedge (local: |x| <= h, y >= -h, z >= -h, y + z <= 0), or kNoHitT.
template <class F, class B>
F ray_wedge(const Ray& ray, F cx, F cy, F cz, F c, F s) {
  using O = Ops<F, B>;
  const F h(kRampHalf);
  const LocalRay<F> l(ray, cx, cy, cz, c, s);
  const F ox = l.ox, oy = l.oy, oz = l.oz, dx = l.dx, dy = l.dy, dz = l.dz;
  F t0(0.0f), t1(ray.max_t);
  B empty = t0 > t1;
  clip<F, B>(h - ox, dx, t0, t1, empty);
  clip<F, B>(h + ox, F(0.0f) - dx, t0, t1, empty);
  clip<F, B>(h + oy, F(0.0f) - dy, t0, t1, empty);
  clip<F, B>(h + oz, F(0.0f) - dz, t0, t1, empty);
  clip<F, B>(F(0.0f) - (oy + oz), dy + dz, t0, t1, empty);
  return O::select(empty | (t0 > t1), F(kNoHitT), t0);
}

// Entry distance into a sphere (0 from inside), or kNoHitT.
template <class F, class B>
F ray_sphere(const Ray& ray, F cx, F cy, F cz, F r) {
  using O = Ops<F, B>;
  const F mx = F(ray.ox) - cx, my = F(ray.oy) - cy, mz = F(ray.oz) - cz;
  const F b = mx * F(ray.dx) + my * F(ray.dy) + mz * F(ray.dz);
  const F c = mx * mx + my * my + mz * mz - r * r;
  const F disc = b * b - c;
  const F zero(0.0f);
  const F t = F(0.0f) - b - O::sqrt(O::max(disc, zero));
  const B miss = ((b > zero) & (c > zero)) | (disc < zero) | (t > F(ray.max_t));
  return O::select(c <= zero, zero, O::select(miss, F(kNoHitT), t));
}

// Keeps the nearer of (t, id) per lane; equal distances keep the earlier (lower) id.
void keep_nearest(float t, int id, RayHit& best) {
  if (t < best.t) best = RayHit{t, id};
}

}  // namespace

int ray_simd_width() {
  return int(xsimd::batch<float>::size);
}

RayHit first_hit_scalar(const ShapesView& s, const Ray& ray) {
  RayHit best{kNoHitT, -1};
  for (int i = 0; i < s.num_boxes; ++i) {
    const float t = ray_box<float, bool>(ray, s.box_cx[i], s.box_cy[i], s.box_cz[i], s.box_hx[i], s.box_hy[i],
                                         s.box_hz[i], s.box_c[i], s.box_s[i]);
    if (i != ray.skip_id) keep_nearest(t, i, best);
  }
  for (int i = 0; i < s.num_wedges; ++i) {
    const float t =
        ray_wedge<float, bool>(ray, s.wedge_cx[i], s.wedge_cy[i], s.wedge_cz[i], s.wedge_c[i], s.wedge_s[i]);
    if (s.wedge_id(i) != ray.skip_id) keep_nearest(t, s.wedge_id(i), best);
  }
  for (int i = 0; i < s.num_spheres; ++i) {
    const float t =
        ray_sphere<float, bool>(ray, s.sphere_cx[i], s.sphere_cy[i], s.sphere_cz[i], s.sphere_r[i]);
    if (s.sphere_id(i) != ray.skip_id) keep_nearest(t, s.sphere_id(i), best);
  }
  if (best.t >= kNoHitT) best.id = -1;
  return best;
}

RayHit first_hit(const ShapesView& s, const Ray& ray) {
  using F = xsimd::batch<float>;
  using B = xsimd::batch_bool<float>;
  constexpr int W = int(F::size);
  static_assert(kRayWidth % W == 0, "padding must be a multiple of the SIMD width");
  alignas(64) float lane_t[W];
  RayHit best{kNoHitT, -1};
  // Per block: distances of W shapes at once, then a scalar scan of the block in id order.
  auto scan = [&](const F& t, int first_id) {
    t.store_aligned(lane_t);
    for (int l = 0; l < W; ++l) {
      if (first_id + l != ray.skip_id) keep_nearest(lane_t[l], first_id + l, best);
    }
  };
  for (int i = 0; i < s.num_boxes; i += W) {
    const F t = ray_box<F, B>(ray, F::load_unaligned(s.box_cx + i), F::load_unaligned(s.box_cy + i),
                              F::load_unaligned(s.box_cz + i), F::load_unaligned(s.box_hx + i),
                              F::load_unaligned(s.box_hy + i), F::load_unaligned(s.box_hz + i),
                              F::load_unaligned(s.box_c + i), F::load_unaligned(s.box_s + i));
    if (xsimd::any(t < F(best.t))) scan(t, i);
  }
  for (int i = 0; i < s.num_wedges; i += W) {
    const F t = ray_wedge<F, B>(ray, F::load_unaligned(s.wedge_cx + i), F::load_unaligned(s.wedge_cy + i),
                                F::load_unaligned(s.wedge_cz + i), F::load_unaligned(s.wedge_c + i),
                                F::load_unaligned(s.wedge_s + i));
    if (xsimd::any(t < F(best.t))) scan(t, s.wedge_id(i));
  }
  for (int i = 0; i < s.num_spheres; i += W) {
    const F t = ray_sphere<F, B>(ray, F::load_unaligned(s.sphere_cx + i), F::load_unaligned(s.sphere_cy + i),
                                 F::load_unaligned(s.sphere_cz + i), F::load_unaligned(s.sphere_r + i));
    if (xsimd::any(t < F(best.t))) scan(t, s.sphere_id(i));
  }
  if (best.t >= kNoHitT) best.id = -1;
  return best;
}

}  // namespace hns::batch
