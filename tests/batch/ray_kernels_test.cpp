// The vectorised ray kernel equals its scalar reference bit for bit, and agrees with the double-precision
// geometry of the physics layer.
#include "batch/ray_kernels.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "physics/geometry.hpp"
#include "physics/rng.hpp"

namespace hns::batch {
namespace {

// Random shapes in a 6 x 6 m arena: `boxes`, `wedges` and `spheres` real ones, the rest of each padded
// array parked below the floor.
struct RandomShapes {
  std::vector<float> bcx, bcy, bcz, bhx, bhy, bhz, bc, bs, wcx, wcy, wcz, wc, ws, scx, scy, scz, sr;
  int nb, nw, ns;
  RandomShapes(physics::Rng& rng, int boxes, int wedges, int spheres) {
    auto pad = [](int n) { return std::max(kRayWidth, (n + kRayWidth - 1) / kRayWidth * kRayWidth); };
    nb = pad(boxes), nw = pad(wedges), ns = pad(spheres);
    for (auto* v : {&bcx, &bcy, &bhx, &bhy, &bhz, &bs}) v->assign(nb, 0.0f);
    bcz.assign(nb, kParkedZ);
    bc.assign(nb, 1.0f);
    for (auto* v : {&wcx, &wcy, &ws}) v->assign(nw, 0.0f);
    wcz.assign(nw, kParkedZ);
    wc.assign(nw, 1.0f);
    for (auto* v : {&scx, &scy}) v->assign(ns, 0.0f);
    scz.assign(ns, kParkedZ);
    sr.assign(ns, 0.01f);
    auto u = [&](double lo, double hi) { return float(rng.uniform(lo, hi)); };
    for (int i = 0; i < boxes; ++i) {
      const float yaw = u(-3.2, 3.2);
      bcx[i] = u(0, 6), bcy[i] = u(0, 6), bhz[i] = u(0.1, 1.0), bcz[i] = bhz[i];
      bhx[i] = u(0.05, 0.9), bhy[i] = u(0.05, 0.9), bc[i] = std::cos(yaw), bs[i] = std::sin(yaw);
    }
    for (int i = 0; i < wedges; ++i) {
      const float yaw = u(-3.2, 3.2);
      wcx[i] = u(0, 6), wcy[i] = u(0, 6), wcz[i] = 0.25f, wc[i] = std::cos(yaw), ws[i] = std::sin(yaw);
    }
    for (int i = 0; i < spheres; ++i)
      scx[i] = u(0, 6), scy[i] = u(0, 6), scz[i] = u(0.15, 0.7), sr[i] = 0.15f;
  }
  ShapesView view() const {
    return ShapesView{bcx.data(), bcy.data(), bcz.data(), bhx.data(), bhy.data(), bhz.data(), bc.data(),
                      bs.data(),  nb,         wcx.data(), wcy.data(), wcz.data(), wc.data(),  ws.data(),
                      nw,         scx.data(), scy.data(), scz.data(), sr.data(),  ns};
  }
};

Ray random_ray(physics::Rng& rng, const ShapesView& v) {
  const double az = rng.uniform(-3.2, 3.2), el = rng.uniform(-0.3, 0.3);
  return Ray{
      float(rng.uniform(0, 6)),           float(rng.uniform(0, 6)),
      float(rng.uniform(0.1, 0.8)),       float(std::cos(el) * std::cos(az)),
      float(std::cos(el) * std::sin(az)), float(std::sin(el)),
      float(rng.uniform(0.5, 9.0)),       rng.uniform_int(-1, v.num_boxes + v.num_wedges + v.num_spheres)};
}

// Every count of real shapes from 0 to 2·width+1, so every tail of a SIMD block is exercised.
TEST(RayKernels, VectorEqualsScalarForEveryTailLength) {
  physics::Rng rng(3, 0, 0);
  const int max_count = 2 * ray_simd_width() + 1;
  int hits = 0;
  for (int count = 0; count <= max_count; ++count) {
    const RandomShapes shapes(rng, count, count % 4, (count * 3) % (max_count + 1));
    const ShapesView v = shapes.view();
    for (int k = 0; k < 400; ++k) {
      const Ray ray = random_ray(rng, v);
      const RayHit a = first_hit(v, ray), b = first_hit_scalar(v, ray);
      ASSERT_EQ(a.id, b.id) << "count " << count << " ray " << k;
      ASSERT_EQ(std::memcmp(&a.t, &b.t, sizeof(float)), 0) << "count " << count << " ray " << k;
      hits += a.id >= 0;
    }
  }
  EXPECT_GT(hits, 1000) << "the random rays must actually hit things";
}

// Against the physics layer's double-precision reference: same first shape and distance within 1e-4 m,
// except for near-ties where float rounding may pick the other of two shapes.
TEST(RayKernels, AgreesWithDoublePrecisionGeometry) {
  physics::Rng rng(4, 0, 0);
  int compared = 0, disagreed = 0;
  for (int scene = 0; scene < 50; ++scene) {
    const RandomShapes s(rng, 12, 2, 5);
    const ShapesView v = s.view();
    std::vector<physics::OrientedBox> boxes;
    std::vector<physics::Wedge> wedges;
    std::vector<physics::Sphere> spheres;
    for (int i = 0; i < 12; ++i)
      boxes.push_back({s.bcx[i], s.bcy[i], s.bcz[i], s.bhx[i], s.bhy[i], s.bhz[i], s.bc[i], s.bs[i]});
    for (int i = 0; i < 2; ++i) wedges.push_back({s.wcx[i], s.wcy[i], s.wcz[i], s.wc[i], s.ws[i]});
    for (int i = 0; i < 5; ++i) spheres.push_back({s.scx[i], s.scy[i], s.scz[i], s.sr[i]});
    const physics::Occluders occ{{}, boxes, wedges, spheres};
    for (int k = 0; k < 200; ++k) {
      Ray ray = random_ray(rng, v);
      const int skip_sphere = rng.uniform_int(-1, 5);
      ray.skip_id = skip_sphere >= 0 ? v.sphere_id(skip_sphere) : -1;
      const RayHit a = first_hit(v, ray);
      const double o[3] = {ray.ox, ray.oy, ray.oz}, d[3] = {ray.dx, ray.dy, ray.dz};
      const physics::RayHit ref = physics::cast_ray(occ, o, d, ray.max_t, skip_sphere);
      int ref_id = -1;
      if (ref.kind == physics::HitKind::kBox) ref_id = ref.index;
      if (ref.kind == physics::HitKind::kRamp) ref_id = v.wedge_id(ref.index);
      if (ref.kind == physics::HitKind::kAgent) ref_id = v.sphere_id(ref.index);
      ++compared;
      if (a.id != ref_id) {
        ++disagreed;
        continue;
      }
      if (a.id >= 0) {
        EXPECT_NEAR(a.t, ref.t, 1e-4);
      }
    }
  }
  EXPECT_LE(disagreed, compared / 500) << disagreed << " of " << compared << " rays hit another shape";
}

}  // namespace
}  // namespace hns::batch
