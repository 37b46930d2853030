// The fan kernel (vectorised across rays) equals its scalar reference bit for bit for every fan length,
// never reads a padding slot, skips the caster, and agrees with the double-precision geometry of the
// physics layer.
#include "batch/ray_kernels.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "physics/geometry.hpp"
#include "physics/rng.hpp"

namespace hns::batch {
namespace {

// Random shapes in a 6 x 6 m arena: `boxes`, `wedges` and `spheres` live ones followed by `pad` padding
// slots of each kind. Every third box is axis-aligned, as walls are. Padding slots hold `padding_box`
// shapes: parked below the floor, or a giant shape over the whole arena that any ray reading it would hit.
struct RandomShapes {
  std::vector<float> bcx, bcy, bcz, bhx, bhy, bhz, bc, bs, wcx, wcy, wcz, wc, ws, scx, scy, scz, sr;
  std::vector<float> ccx, ccy, cr, ch;  // cylinders: live ones only (the batch has one slot, used or not)
  int nb, nw, ns, live_b, live_w, live_s;
  RandomShapes(physics::Rng& rng, int boxes, int wedges, int spheres, int pad = 3, bool giant_padding = false,
               int cylinders = 0)
      : nb(boxes + pad), nw(wedges + pad), ns(spheres + pad), live_b(boxes), live_w(wedges), live_s(spheres) {
    const float pz = giant_padding ? 0.0f : kParkedZ, ph = giant_padding ? 100.0f : 0.01f;
    for (auto* v : {&bcx, &bcy}) v->assign(nb, giant_padding ? 3.0f : 0.0f);
    bs.assign(nb, 0.0f);
    for (auto* v : {&bhx, &bhy, &bhz}) v->assign(nb, ph);
    bcz.assign(nb, pz);
    bc.assign(nb, 1.0f);
    for (auto* v : {&wcx, &wcy}) v->assign(nw, 3.0f);
    ws.assign(nw, 0.0f);
    wcz.assign(nw, giant_padding ? 0.25f : kParkedZ);
    wc.assign(nw, 1.0f);
    for (auto* v : {&scx, &scy}) v->assign(ns, 3.0f);
    scz.assign(ns, pz);
    sr.assign(ns, ph);
    auto u = [&](double lo, double hi) { return float(rng.uniform(lo, hi)); };
    for (int i = 0; i < boxes; ++i) {
      const float yaw = i % 3 == 0 ? 0.0f : u(-3.2, 3.2);
      bcx[i] = u(0, 6), bcy[i] = u(0, 6), bhz[i] = u(0.1, 1.0), bcz[i] = bhz[i];
      bhx[i] = u(0.05, 0.9), bhy[i] = u(0.05, 0.9);
      bc[i] = i % 3 == 0 ? 1.0f : std::cos(yaw), bs[i] = i % 3 == 0 ? 0.0f : std::sin(yaw);
    }
    for (int i = 0; i < wedges; ++i) {
      const float yaw = u(-3.2, 3.2);
      wcx[i] = u(0, 6), wcy[i] = u(0, 6), wcz[i] = 0.25f, wc[i] = std::cos(yaw), ws[i] = std::sin(yaw);
    }
    for (int i = 0; i < spheres; ++i)
      scx[i] = u(0, 6), scy[i] = u(0, 6), scz[i] = u(0.15, 0.7), sr[i] = 0.15f;
    for (int i = 0; i < cylinders; ++i) {
      ccx.push_back(u(0, 6)), ccy.push_back(u(0, 6)), cr.push_back(u(0.2, 1.0)), ch.push_back(u(0.2, 1.0));
    }
  }
  ShapesView view() const {
    ShapesView v;
    v.box_cx = bcx.data(), v.box_cy = bcy.data(), v.box_cz = bcz.data();
    v.box_hx = bhx.data(), v.box_hy = bhy.data(), v.box_hz = bhz.data();
    v.box_c = bc.data(), v.box_s = bs.data(), v.num_boxes = nb, v.live_boxes = live_b;
    v.wedge_cx = wcx.data(), v.wedge_cy = wcy.data(), v.wedge_cz = wcz.data();
    v.wedge_c = wc.data(), v.wedge_s = ws.data(), v.num_wedges = nw, v.live_wedges = live_w;
    v.sphere_cx = scx.data(), v.sphere_cy = scy.data(), v.sphere_cz = scz.data(), v.sphere_r = sr.data();
    v.num_spheres = ns, v.live_spheres = live_s;
    v.cyl_cx = ccx.data(), v.cyl_cy = ccy.data(), v.cyl_r = cr.data(), v.cyl_h = ch.data();
    v.num_cylinders = v.live_cylinders = int(ccx.size());
    return v;
  }
};

// A fan of `count` rays from a random origin: random unit directions, a few of them exactly horizontal or
// along an axis (as lidar rays and walls meet), and random lengths (some zero).
struct RandomFan {
  std::vector<float> dx, dy, dz, max_t;
  RayFan fan{};
  RandomFan(physics::Rng& rng, int count, int skip_id) : dx(count), dy(count), dz(count), max_t(count) {
    for (int i = 0; i < count; ++i) {
      const double az = rng.uniform(-3.2, 3.2), el = rng.uniform(-0.3, 0.3);
      dx[i] = float(std::cos(el) * std::cos(az)), dy[i] = float(std::cos(el) * std::sin(az));
      dz[i] = float(std::sin(el));
      switch (rng.uniform_int(0, 8)) {
        case 0:
          dx[i] = float(std::cos(az)), dy[i] = float(std::sin(az)), dz[i] = 0.0f;
          break;
        case 1:
          dx[i] = 0.0f, dy[i] = az > 0 ? 1.0f : -1.0f, dz[i] = 0.0f;
          break;
        case 2:
          dx[i] = az > 0 ? 1.0f : -1.0f, dy[i] = 0.0f, dz[i] = 0.0f;
          break;
        default:
          break;
      }
      max_t[i] = rng.uniform_int(0, 20) == 0 ? 0.0f : float(rng.uniform(0.5, 9.0));
    }
    fan = RayFan{float(rng.uniform(0, 6)),
                 float(rng.uniform(0, 6)),
                 float(rng.uniform(0.1, 0.8)),
                 dx.data(),
                 dy.data(),
                 dz.data(),
                 max_t.data(),
                 count,
                 skip_id};
  }
};

struct Hits {
  std::vector<float> t;
  std::vector<int32_t> id;
  explicit Hits(int n) : t(size_t(n) + 1, -7.0f), id(size_t(n) + 1, -7) {}
};

// Every fan length from 0 to 3·width+1, so every tail of a SIMD block (and none) is exercised, against
// scenes of several sizes; the entry past the fan's end must stay untouched.
TEST(RayKernels, VectorEqualsScalarForEveryFanLength) {
  physics::Rng rng(3, 0, 0);
  const int max_count = 3 * ray_simd_width() + 1;
  int hits = 0, rays = 0;
  for (int scene = 0; scene < 12; ++scene) {
    const RandomShapes shapes(rng, scene, scene % 4, (scene * 5) % 9, scene % 3, false, scene % 3);
    const ShapesView v = shapes.view();
    for (int count = 0; count <= max_count; ++count) {
      for (int rep = 0; rep < 8; ++rep) {
        const RandomFan f(rng, count, rng.uniform_int(-1, v.num_boxes + v.num_wedges + v.num_spheres));
        Hits a(count), b(count);
        first_hits(v, f.fan, a.t.data(), a.id.data());
        first_hits_scalar(v, f.fan, b.t.data(), b.id.data());
        for (int i = 0; i < count; ++i) {
          ASSERT_EQ(a.id[i], b.id[i]) << "scene " << scene << " count " << count << " ray " << i;
          ASSERT_EQ(std::memcmp(&a.t[i], &b.t[i], sizeof(float)), 0)
              << "scene " << scene << " count " << count << " ray " << i << ": " << a.t[i] << " vs "
              << b.t[i];
          ASSERT_EQ(a.id[i] < 0, a.t[i] == kNoHitT);
          hits += a.id[i] >= 0;
        }
        ASSERT_EQ(a.id[count], -7) << "wrote past the fan";
        ASSERT_EQ(a.t[count], -7.0f) << "wrote past the fan";
        rays += count;
      }
    }
  }
  EXPECT_GT(hits, rays / 5) << "the random rays must actually hit things";
}

// Slots past the live counts are never read: a giant shape there changes nothing.
TEST(RayKernels, PaddingSlotsAreNeverRead) {
  physics::Rng rng_a(5, 0, 0), rng_b(5, 0, 0), rays(6, 0, 0);
  const RandomShapes parked(rng_a, 7, 2, 4, 5, false), giant(rng_b, 7, 2, 4, 5, true);
  int hits = 0;
  for (int k = 0; k < 200; ++k) {
    const RandomFan f(rays, 30, -1);
    Hits a(30), b(30);
    first_hits(parked.view(), f.fan, a.t.data(), a.id.data());
    first_hits(giant.view(), f.fan, b.t.data(), b.id.data());
    for (int i = 0; i < 30; ++i) {
      ASSERT_EQ(a.id[i], b.id[i]) << "fan " << k << " ray " << i;
      ASSERT_EQ(a.t[i], b.t[i]) << "fan " << k << " ray " << i;
      hits += a.id[i] >= 0;
    }
  }
  EXPECT_GT(hits, 1000);
  // The check above can fail: with the padding counted as live, most rays start inside a giant shape.
  ShapesView all = giant.view();
  all.live_boxes = all.num_boxes;
  int changed = 0;
  for (int k = 0; k < 20; ++k) {
    const RandomFan f(rays, 8, -1);
    Hits a(8), b(8);
    first_hits(giant.view(), f.fan, a.t.data(), a.id.data());
    first_hits(all, f.fan, b.t.data(), b.id.data());
    for (int i = 0; i < 8; ++i) changed += a.id[i] != b.id[i];
  }
  EXPECT_GT(changed, 80);
}

// A fan from inside a sphere hits it at 0 unless that sphere is the caster, which every ray then ignores.
TEST(RayKernels, CasterIsSkipped) {
  physics::Rng rng(7, 0, 0);
  RandomShapes s(rng, 0, 0, 2, 0);
  s.scx = {1.0f, 4.0f}, s.scy = {1.0f, 1.0f}, s.scz = {0.5f, 0.5f}, s.sr = {0.15f, 0.15f};
  const ShapesView v = s.view();
  const float dx[2] = {1.0f, -1.0f}, dy[2] = {0.0f, 0.0f}, dz[2] = {0.0f, 0.0f}, len[2] = {6.0f, 6.0f};
  float t[2];
  int32_t id[2];
  first_hits(v, RayFan{1.0f, 1.0f, 0.5f, dx, dy, dz, len, 2, -1}, t, id);
  EXPECT_EQ(id[0], v.sphere_id(0));
  EXPECT_EQ(t[0], 0.0f);
  first_hits(v, RayFan{1.0f, 1.0f, 0.5f, dx, dy, dz, len, 2, v.sphere_id(0)}, t, id);
  EXPECT_EQ(id[0], v.sphere_id(1)) << "the ray along +x reaches the other agent";
  EXPECT_NEAR(t[0], 3.0f - 0.15f, 1e-5f);
  EXPECT_EQ(id[1], -1) << "nothing along -x";
  EXPECT_EQ(t[1], kNoHitT);
}

// Agents as sphere bodies of three slots (body, two arms): a hit on an arm reports the body's id, the
// caster's arms are skipped with it, and the early out past a body's reach changes no bit (vector and
// scalar).
TEST(RayKernels, SphereBodiesShareTheirIdAndTheEarlyOutChangesNothing) {
  physics::Rng rng(8, 0, 0);
  int arm_hits = 0, rays = 0;
  for (int scene = 0; scene < 20; ++scene) {
    const int bodies = 1 + scene % 6;
    RandomShapes s(rng, 6, 1, 3 * bodies, 0);
    for (int b = 0; b < bodies; ++b) {
      const float centre[3] = {s.scx[3 * b], s.scy[3 * b], s.scz[3 * b]};
      const float yaw = float(rng.uniform(-3.2, 3.2));
      float arm[2][3];
      physics::arm_centres(centre, std::cos(yaw), std::sin(yaw), arm);
      for (int k = 0; k < 2; ++k) {
        s.scx[3 * b + 1 + k] = arm[k][0], s.scy[3 * b + 1 + k] = arm[k][1], s.scz[3 * b + 1 + k] = arm[k][2];
        s.sr[3 * b + 1 + k] = float(physics::kArmRadius);
      }
    }
    ShapesView reach = s.view();
    reach.spheres_per_body = 3;
    reach.body_reach = float(physics::kAgentReach);
    ShapesView every = reach;
    every.body_reach = 0.0f;
    ShapesView no_arms = reach;  // the same bodies without arms: radius-0 arms are never hit from outside
    std::vector<float> zero_r = s.sr;
    for (int b = 0; b < bodies; ++b) zero_r[3 * b + 1] = zero_r[3 * b + 2] = 0.0f;
    no_arms.sphere_r = zero_r.data();
    for (int count = 0; count <= 2 * ray_simd_width() + 1; ++count) {
      for (int rep = 0; rep < 6; ++rep) {
        const int skip = rng.uniform_int(-1, bodies);
        RandomFan f(rng, count, skip >= 0 ? reach.sphere_id(skip) : -1);
        // Every other ray aims near a random arm, so that arms are grazed and hit.
        for (int i = 0; i < count; i += 2) {
          const int k = 3 * rng.uniform_int(0, bodies) + 1 + rng.uniform_int(0, 2);
          const double tx = s.scx[k] + rng.uniform(-0.06, 0.06) - f.fan.ox;
          const double ty = s.scy[k] + rng.uniform(-0.06, 0.06) - f.fan.oy;
          const double tz = s.scz[k] + rng.uniform(-0.06, 0.06) - f.fan.oz;
          const double len = std::sqrt(tx * tx + ty * ty + tz * tz);
          f.dx[i] = float(tx / len), f.dy[i] = float(ty / len), f.dz[i] = float(tz / len);
        }
        Hits a(count), b(count), c(count), d(count);
        first_hits(reach, f.fan, a.t.data(), a.id.data());
        first_hits(every, f.fan, b.t.data(), b.id.data());
        first_hits_scalar(reach, f.fan, c.t.data(), c.id.data());
        first_hits(no_arms, f.fan, d.t.data(), d.id.data());
        for (int i = 0; i < count; ++i) {
          ASSERT_EQ(a.id[i], b.id[i]);
          ASSERT_EQ(std::memcmp(&a.t[i], &b.t[i], sizeof(float)), 0) << "the early out changed a result";
          ASSERT_EQ(a.id[i], c.id[i]);
          ASSERT_EQ(std::memcmp(&a.t[i], &c.t[i], sizeof(float)), 0) << "vector and scalar differ";
          ASSERT_LT(a.id[i], reach.sphere_id(bodies)) << "every sphere hit reports its body";
          if (skip >= 0) {
            ASSERT_NE(a.id[i], reach.sphere_id(skip)) << "the caster's arms are skipped";
          }
          arm_hits += a.id[i] >= reach.sphere_id(0) && (a.t[i] != d.t[i] || a.id[i] != d.id[i]);
          ++rays;
        }
      }
    }
  }
  EXPECT_GT(arm_hits, 500) << "of " << rays << " rays: the arms must be hit for the check to mean something";
}

// Against the physics layer's double-precision reference: same first shape and distance within 1e-4 m,
// except for near-ties where float rounding may pick the other of two shapes.
TEST(RayKernels, AgreesWithDoublePrecisionGeometry) {
  physics::Rng rng(4, 0, 0);
  int compared = 0, disagreed = 0, hits = 0, cylinder_hits = 0;
  for (int scene = 0; scene < 50; ++scene) {
    const RandomShapes s(rng, 12, 2, 5, 3, false, 2);
    const ShapesView v = s.view();
    std::vector<physics::OrientedBox> boxes;
    std::vector<physics::Wedge> wedges;
    std::vector<physics::Sphere> spheres;
    for (int i = 0; i < 12; ++i)
      boxes.push_back({s.bcx[i], s.bcy[i], s.bcz[i], s.bhx[i], s.bhy[i], s.bhz[i], s.bc[i], s.bs[i]});
    for (int i = 0; i < 2; ++i) wedges.push_back({s.wcx[i], s.wcy[i], s.wcz[i], s.wc[i], s.ws[i]});
    for (int i = 0; i < 5; ++i) spheres.push_back({s.scx[i], s.scy[i], s.scz[i], s.sr[i]});
    std::vector<physics::Cylinder> cylinders;
    for (int i = 0; i < 2; ++i) cylinders.push_back({s.ccx[i], s.ccy[i], s.cr[i], s.ch[i]});
    const physics::Occluders occ{{}, boxes, wedges, spheres, {}, cylinders};
    for (int k = 0; k < 10; ++k) {
      const int skip_sphere = rng.uniform_int(-1, 5);
      const RandomFan f(rng, 20, skip_sphere >= 0 ? v.sphere_id(skip_sphere) : -1);
      Hits a(20);
      first_hits(v, f.fan, a.t.data(), a.id.data());
      for (int i = 0; i < 20; ++i) {
        // The reference keeps hits strictly nearer than max_t, the kernel up to max_t: they differ only for
        // a zero-length ray from inside a shape, which the batch never casts.
        if (f.max_t[i] == 0.0f) continue;
        const double o[3] = {f.fan.ox, f.fan.oy, f.fan.oz}, d[3] = {f.dx[i], f.dy[i], f.dz[i]};
        const physics::RayHit ref = physics::cast_ray(occ, o, d, f.max_t[i], skip_sphere);
        int ref_id = -1;
        if (ref.kind == physics::HitKind::kBox) ref_id = ref.index;
        if (ref.kind == physics::HitKind::kRamp) ref_id = v.wedge_id(ref.index);
        if (ref.kind == physics::HitKind::kAgent) ref_id = v.sphere_id(ref.index);
        if (ref.kind == physics::HitKind::kCylinder) ref_id = v.cylinder_id(ref.index);
        ++compared;
        cylinder_hits += ref.kind == physics::HitKind::kCylinder;
        if (a.id[i] != ref_id) {
          ++disagreed;
          continue;
        }
        if (a.id[i] >= 0) {
          ++hits;
          EXPECT_NEAR(a.t[i], ref.t, 1e-4);
        }
      }
    }
  }
  EXPECT_GT(hits, compared / 5);
  EXPECT_GT(cylinder_hits, compared / 50) << "the rays must hit the cylinders too";
  EXPECT_LE(disagreed, compared / 500) << disagreed << " of " << compared << " rays hit another shape";
}

}  // namespace
}  // namespace hns::batch
