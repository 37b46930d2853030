// Ray casting against one env's shapes for line of sight and lidar (docs/game.md §4.1, §4.2, §14.6, §14.7).
//
// The kernel casts a *fan*: rays that share one origin (an agent's lines of sight to its targets, or its 30
// lidar rays). It is vectorised across rays with xsimd: each shape's own quantities (its frame, the origin
// in that frame) are computed once as scalars and broadcast, and every lane keeps its nearest hit with a
// branch-free select. A scalar reference does the same arithmetic one ray at a time; the two agree bit for
// bit.
//
// Shapes are float structure-of-arrays. Slots [0, live) of each kind hold this episode's shapes; later slots
// are padding the kernel never reads (the batch parks them far below the floor).
#pragma once

#include <cstdint>

namespace hns::batch {

// Lanes of the vector kernel (floats per register of the build's instruction set).
int ray_simd_width();
inline constexpr float kParkedZ = -1.0e4f;  // m, z of a padding slot's centre
inline constexpr float kNoHitT = 1.0e30f;   // distance reported for a ray that hits nothing

// Read-only view of one env's shapes. Shape ids: box slots [0, num_boxes), wedge slots next, then one id per
// sphere *body*: spheres come in groups of spheres_per_body slots (an agent and its two arms), and sphere
// slot k reports the id of body k / spheres_per_body. Boxes hold walls and movable boxes alike; yaw as
// cos/sin; ramps are wedges of the fixed ramp size.
struct ShapesView {
  const float *box_cx, *box_cy, *box_cz;        // centre, m
  const float *box_hx, *box_hy, *box_hz;        // half extents, m
  const float *box_c, *box_s;                   // cos, sin of yaw
  int num_boxes, live_boxes;                    // slots, and slots [0, live) in use
  const float *wedge_cx, *wedge_cy, *wedge_cz;  // bounding-box centre, m
  const float *wedge_c, *wedge_s;               // cos, sin of yaw
  int num_wedges, live_wedges;
  const float *sphere_cx, *sphere_cy, *sphere_cz, *sphere_r;  // centre and radius, m
  int num_spheres, live_spheres;                              // slots, and slots [0, live) in use
  int spheres_per_body = 1;                                   // slots per sphere body
  // Every sphere of a body lies within this distance of the body's first sphere's centre (m). A block of
  // rays that all pass farther away skips the body's other spheres: an early out that changes no result.
  float body_reach = 0.0f;
  // Static vertical cylinders on the floor (the shelter task's target): axis (cx, cy), radius, height (m).
  const float *cyl_cx = nullptr, *cyl_cy = nullptr, *cyl_r = nullptr, *cyl_h = nullptr;
  int num_cylinders = 0, live_cylinders = 0;

  int wedge_id(int i) const { return num_boxes + i; }
  // The id of sphere body i (slots [i·spheres_per_body, (i + 1)·spheres_per_body)).
  int sphere_id(int i) const { return num_boxes + num_wedges + i; }
  // The id of cylinder i, after every sphere body's.
  int cylinder_id(int i) const { return sphere_id(num_spheres / spheres_per_body) + i; }
};

// `count` rays from one origin: per ray a unit direction and a length (hits farther away are ignored).
struct RayFan {
  float ox, oy, oz;           // origin, m
  const float *dx, *dy, *dz;  // unit directions (count each)
  const float* max_t;         // lengths, m (count)
  int count;                  // any count >= 0; no padding needed
  int skip_id;                // a shape or sphere body every ray ignores (the caster's own), -1 for none
};

// Per ray of the fan, the first shape hit: t[i] its distance (kNoHitT if none within max_t) and id[i] its id
// (-1 if none); on exact ties the lower id. t and id hold fan.count entries. Both give bit-identical results.
void first_hits(const ShapesView& shapes, const RayFan& fan, float* t, int32_t* id);
void first_hits_scalar(const ShapesView& shapes, const RayFan& fan, float* t, int32_t* id);

}  // namespace hns::batch
