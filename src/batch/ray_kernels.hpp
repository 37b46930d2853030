// Ray casting against one env's shapes, vectorised across shapes with xsimd, plus the scalar reference the
// tests compare it to. These kernels drive line of sight and lidar (SPEC.md §4.1, §4.2, §14.6, §14.7).
//
// Shapes are float structure-of-arrays, each array padded to a multiple of kRayWidth. Padding shapes sit
// far below the floor (z = kParkedZ) and are never hit by a ray of bounded length.
#pragma once

#include <cstdint>

namespace hns::batch {

// Lanes of the vector kernels (floats per register of the build's instruction set).
int ray_simd_width();
inline constexpr int kRayWidth = 8;  // arrays are padded to a multiple of this (>= any SIMD width used)
inline constexpr float kParkedZ = -1.0e4f;
inline constexpr float kNoHitT = 1.0e30f;

// Read-only view of one env's shapes. Shape ids: boxes [0, num_boxes), wedges next, spheres last.
// Boxes hold walls and movable boxes alike; yaw as cos/sin.
struct ShapesView {
  const float *box_cx, *box_cy, *box_cz, *box_hx, *box_hy, *box_hz, *box_c, *box_s;
  int num_boxes;  // a multiple of kRayWidth
  const float *wedge_cx, *wedge_cy, *wedge_cz, *wedge_c, *wedge_s;
  int num_wedges;  // a multiple of kRayWidth
  const float *sphere_cx, *sphere_cy, *sphere_cz, *sphere_r;
  int num_spheres;  // a multiple of kRayWidth

  int wedge_id(int i) const { return num_boxes + i; }
  int sphere_id(int i) const { return num_boxes + num_wedges + i; }
};

struct Ray {
  float ox, oy, oz;  // origin, m
  float dx, dy, dz;  // unit direction
  float max_t;       // hits beyond this distance are ignored, m
  int skip_id;       // a shape the ray ignores (the caster's own body), -1 for none
};

struct RayHit {
  float t;  // kNoHitT if nothing within max_t
  int id;   // -1 if nothing
};

// First shape hit along the ray (lowest id on exact ties). Both give bit-identical results.
RayHit first_hit(const ShapesView& shapes, const Ray& ray);
RayHit first_hit_scalar(const ShapesView& shapes, const Ray& ray);

}  // namespace hns::batch
