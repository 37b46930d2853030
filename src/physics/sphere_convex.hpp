// An exact sphere against convex polyhedron contact, for the ramp's wedge against agents and their arms.
//
// ODE's own sphere-convex collider picks the contact from the face planes and gets the normal wrong where the
// sphere's closest point on the polyhedron is an edge or a vertex: against the top edge of a ramp's vertical
// side cap it returns the slope's normal, which lifts an agent pushing into the cap up and over the ramp
// (MuJoCo, the original's engine, pushes the ramp aside instead). This one finds the polyhedron's closest
// point to the sphere's centre (face interior, edge or vertex) and pushes along the line between them; with
// the centre inside, along the face of least penetration.
#pragma once

#include <span>

namespace hns::physics {

// A convex polyhedron in its own frame: outward face planes (a, b, c, d: points p inside have
// a·px + b·py + c·pz <= d, (a, b, c) unit), vertices (x, y, z) and edges (pairs of vertex indices).
struct ConvexShape {
  std::span<const double> planes;  // 4 per face
  std::span<const double> points;  // 3 per vertex
  std::span<const int> edges;      // 2 per edge
};

struct SphereContact {
  double pos[3];     // m, world: the polyhedron's point closest to the sphere's centre
  double normal[3];  // unit, world, out of the polyhedron towards the sphere
  double depth;      // m, > 0
};

// The contact of a sphere (world centre, radius) with the polyhedron at world position `pos` and rotation
// `rot` (3 x 4 row major, ODE's layout): true and `out` filled where they overlap, false otherwise.
bool collide_sphere_convex(const double centre[3], double radius, const double pos[3], const double rot[12],
                           const ConvexShape& shape, SphereContact& out);

}  // namespace hns::physics
