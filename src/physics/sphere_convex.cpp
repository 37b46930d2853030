#include "physics/sphere_convex.hpp"

#include <cmath>
#include <limits>

namespace hns::physics {
namespace {

double dot(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

// Closest point to p on the segment a-b.
void closest_on_segment(const double p[3], const double a[3], const double b[3], double q[3]) {
  const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  const double len_sq = dot(ab, ab);
  double t = len_sq > 0 ? dot(ap, ab) / len_sq : 0.0;
  t = t < 0 ? 0 : (t > 1 ? 1 : t);
  for (int k = 0; k < 3; ++k) q[k] = a[k] + t * ab[k];
}

double dist_sq(const double a[3], const double b[3]) {
  const double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
  return dot(d, d);
}

}  // namespace

bool collide_sphere_convex(const double centre[3], double radius, const double pos[3], const double rot[12],
                           const ConvexShape& shape, SphereContact& out) {
  // The centre in the polyhedron's frame: R^T (centre - pos).
  const double w[3] = {centre[0] - pos[0], centre[1] - pos[1], centre[2] - pos[2]};
  double c[3];
  for (int k = 0; k < 3; ++k) c[k] = rot[k] * w[0] + rot[4 + k] * w[1] + rot[8 + k] * w[2];

  const int faces = int(shape.planes.size() / 4);
  // Signed distances to every face plane; the centre is inside where all are <= 0.
  double best_face_dist = -std::numeric_limits<double>::infinity();
  int best_face = -1;
  bool inside = true;
  for (int f = 0; f < faces; ++f) {
    const double* pl = &shape.planes[4 * f];
    const double s = dot(pl, c) - pl[3];
    if (s > 0) inside = false;
    if (s > best_face_dist) best_face_dist = s, best_face = f;
  }
  if (best_face_dist >= radius) return false;  // separated by a face plane

  double q[3];        // closest point on the surface, local frame
  double n_local[3];  // outward normal, local frame
  double depth;
  if (inside) {
    // Out through the face of least penetration.
    const double* pl = &shape.planes[4 * best_face];
    for (int k = 0; k < 3; ++k) n_local[k] = pl[k], q[k] = c[k] - best_face_dist * pl[k];
    depth = radius - best_face_dist;
  } else {
    // Outside: the closest surface point is a face's interior projection, or lies on an edge (vertices are
    // edge ends). A face's projection counts only where it lies within every other face's plane.
    constexpr double kSlack = 1e-12;
    double best = std::numeric_limits<double>::infinity();
    for (int f = 0; f < faces; ++f) {
      const double* pl = &shape.planes[4 * f];
      const double s = dot(pl, c) - pl[3];
      if (s <= 0) continue;
      const double p[3] = {c[0] - s * pl[0], c[1] - s * pl[1], c[2] - s * pl[2]};
      bool within = true;
      for (int g = 0; g < faces && within; ++g)
        if (g != f) within = dot(&shape.planes[4 * g], p) - shape.planes[4 * g + 3] <= kSlack;
      if (within && s * s < best) {
        best = s * s;
        for (int k = 0; k < 3; ++k) q[k] = p[k];
      }
    }
    for (size_t e = 0; e + 1 < shape.edges.size(); e += 2) {
      double p[3];
      closest_on_segment(c, &shape.points[3 * shape.edges[e]], &shape.points[3 * shape.edges[e + 1]], p);
      const double d = dist_sq(c, p);
      if (d < best) {
        best = d;
        for (int k = 0; k < 3; ++k) q[k] = p[k];
      }
    }
    const double dist = std::sqrt(best);
    if (!(dist < radius) || dist <= 0) return false;
    for (int k = 0; k < 3; ++k) n_local[k] = (c[k] - q[k]) / dist;
    depth = radius - dist;
  }
  // Back to the world frame: R q + pos, R n.
  for (int k = 0; k < 3; ++k) {
    out.pos[k] = pos[k] + rot[4 * k] * q[0] + rot[4 * k + 1] * q[1] + rot[4 * k + 2] * q[2];
    out.normal[k] = rot[4 * k] * n_local[0] + rot[4 * k + 1] * n_local[1] + rot[4 * k + 2] * n_local[2];
  }
  out.depth = depth;
  return true;
}

}  // namespace hns::physics
