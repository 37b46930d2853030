// World's contacts (docs/game.md §1.2, docs/physics.md): the pair friction, friction along the slip, soft
// floor contacts, an agent's arms collided only where they reach, and the exact sphere-ramp contact.
#include <ode/ode.h>

#include <algorithm>
#include <cmath>

#include "physics/world_ode.hpp"

namespace hns::physics::world_detail {
namespace {

GeomInfo* info(dGeomID g) {
  return static_cast<GeomInfo*>(dGeomGetData(g));
}

// A sphere (an agent's body or arm) against the ramp's wedge, the one convex of the world, by the exact
// collider (sphere_convex.hpp) instead of ODE's; the contact as dCollide(g1, g2) would give it (normal out of
// g2 into g1). 0 or 1 contacts.
int collide_sphere_ramp(dGeomID g1, dGeomID g2, dContactGeom* contact) {
  const bool sphere_first = dGeomGetClass(g1) == dSphereClass;
  dGeomID sphere = sphere_first ? g1 : g2;
  dGeomID ramp = sphere_first ? g2 : g1;
  SphereContact c;
  if (!collide_sphere_convex(dGeomGetPosition(sphere), dGeomSphereGetRadius(sphere), dGeomGetPosition(ramp),
                             dGeomGetRotation(ramp), kRampShape, c)) {
    return 0;
  }
  const double sign = sphere_first ? 1.0 : -1.0;
  for (int k = 0; k < 3; ++k) contact->pos[k] = c.pos[k], contact->normal[k] = sign * c.normal[k];
  contact->pos[3] = contact->normal[3] = 0;
  contact->depth = c.depth;
  contact->g1 = g1;
  contact->g2 = g2;
  contact->side1 = contact->side2 = -1;
  return 1;
}

// Contacts between geoms g1 and g2 (of bodies b1 and b2, null for static geoms) with the pair friction
// max(μ1, μ2) (docs/game.md §1.2; ODE's friction pyramid scaled by the normal force, turned along the slip
// below).
void add_contacts(World::Ode* ode, dGeomID g1, dBodyID b1, dGeomID g2, dBodyID b2) {
  dContact contact[kMaxContactsPerPair];
  const int c1 = dGeomGetClass(g1), c2 = dGeomGetClass(g2);
  const int n = (c1 == dSphereClass && c2 == dConvexClass) || (c1 == dConvexClass && c2 == dSphereClass)
                    ? collide_sphere_ramp(g1, g2, &contact[0].geom)
                    : dCollide(g1, g2, kMaxContactsPerPair, &contact[0].geom, sizeof(dContact));
  if (n == 0) return;
  const double mu = std::max(info(g1)->friction, info(g2)->friction);
  for (int i = 0; i < n; ++i) {
    // ODE's convex-box collider returns a zero normal for exactly touching faces; such a contact would
    // poison the whole world with NaN, so it is dropped (the next substep sees a proper overlap).
    const dContactGeom& g = contact[i].geom;
    const double normal_sq =
        g.normal[0] * g.normal[0] + g.normal[1] * g.normal[1] + g.normal[2] * g.normal[2];
    if (!(normal_sq > 0.5 && normal_sq < 1.5) || !std::isfinite(g.depth) ||
        !std::isfinite(g.pos[0] + g.pos[1] + g.pos[2])) {
      continue;
    }
    contact[i].surface.mode = dContactApprox1;
    contact[i].surface.mu = mu;
    // A box's or ramp's floor contacts are soft (docs/physics.md "Contacts"): its weight spreads over its
    // bottom corners by their depth, as in MuJoCo, instead of the rigid solver's arbitrary split, which
    // could put the floor's friction on any corner and turn a pushed ramp or long box the wrong way. (An
    // agent touches the floor at one point: it stays rigid and at its exact height.)
    if (ode->floor_cfm > 0 && (c1 == dPlaneClass || c2 == dPlaneClass) && info(g1) != &ode->agent_info &&
        info(g2) != &ode->agent_info) {
      contact[i].surface.mode |= dContactSoftCFM;
      contact[i].surface.soft_cfm = ode->floor_cfm;
    }
    // A contact that slides has its friction along the slip and none across it (Coulomb: a sliding contact
    // has no grip left sideways). ODE's fixed pyramid would hold a body sliding along x against any sideways
    // push below μN, so an agent running along a ramp's side or a box's face was never deflected.
    if (ode->slip_speed > 0) {
      dVector3 v1 = {0, 0, 0}, v2 = {0, 0, 0};
      if (b1 != nullptr) dBodyGetPointVel(b1, g.pos[0], g.pos[1], g.pos[2], v1);
      if (b2 != nullptr) dBodyGetPointVel(b2, g.pos[0], g.pos[1], g.pos[2], v2);
      double slip[3] = {v1[0] - v2[0], v1[1] - v2[1], v1[2] - v2[2]};
      const double along_normal = slip[0] * g.normal[0] + slip[1] * g.normal[1] + slip[2] * g.normal[2];
      for (int k = 0; k < 3; ++k) slip[k] -= along_normal * g.normal[k];
      const double speed = std::sqrt(slip[0] * slip[0] + slip[1] * slip[1] + slip[2] * slip[2]);
      if (speed > ode->slip_speed) {
        contact[i].surface.mode |= dContactFDir1 | dContactMu2;
        for (int k = 0; k < 3; ++k) contact[i].fdir1[k] = slip[k] / speed;
        contact[i].fdir1[3] = 0;
        contact[i].surface.mu2 = 0;
      }
    }
    dJointID joint = dJointCreateContact(ode->world, ode->contacts, &contact[i]);
    dJointAttach(joint, b1, b2);
  }
}

// Places arm k (geom `arm`, bodyless) of the agent with body `body` and tells whether it may touch the
// axis-aligned box aabb = (x0, x1, y0, y1, z0, z1): whether its own bounding box overlaps it.
bool place_arm(dGeomID arm, dBodyID body, int k, const dReal aabb[6]) {
  const dReal* p = dBodyGetPosition(body);
  const dReal* R = dBodyGetRotation(body);  // 3 x 4, row major
  const double* o = kArmOffset[k];
  double c[3];
  for (int axis = 0; axis < 3; ++axis) {
    c[axis] = p[axis] + R[4 * axis] * o[0] + R[4 * axis + 1] * o[1] + R[4 * axis + 2] * o[2];
    if (c[axis] + kArmRadius < aabb[2 * axis] || c[axis] - kArmRadius > aabb[2 * axis + 1]) return false;
  }
  dGeomSetPosition(arm, c[0], c[1], c[2]);
  return true;
}

}  // namespace

// ODE near callback for a pair whose bounding boxes overlap. An agent's proxy stands for its parts: its
// body sphere always, each arm (placed from the body's pose first) where the arm's own bounding box meets
// the other side's.
void near_callback(void* data, dGeomID g1, dGeomID g2) {
  auto* ode = static_cast<World::Ode*>(data);
  dBodyID b1 = dGeomGetBody(g1);
  dBodyID b2 = dGeomGetBody(g2);
  // Only a pair with an awake dynamic body can produce a contact; a sleeping body touched by an awake one is
  // woken by ODE through the contact.
  const bool awake1 = b1 != nullptr && dBodyIsEnabled(b1) && !dBodyIsKinematic(b1);
  const bool awake2 = b2 != nullptr && dBodyIsEnabled(b2) && !dBodyIsKinematic(b2);
  if (!awake1 && !awake2) return;
  // A held object does not collide with its holder.
  if (b1 != nullptr && b2 != nullptr && dAreConnectedExcluding(b1, b2, dJointTypeContact)) return;
  const GeomInfo* i1 = info(g1);
  const GeomInfo* i2 = info(g2);
  if (i1->num_parts == 0 && i2->num_parts == 0) {
    add_contacts(ode, g1, b1, g2, b2);
    return;
  }
  // Against the floor only an agent's body sphere counts: its arms hang 0.05 m above it.
  const bool floor = dGeomGetClass(g1) == dPlaneClass || dGeomGetClass(g2) == dPlaneClass;
  dReal box1[6], box2[6];
  dGeomGetAABB(g1, box1);
  dGeomGetAABB(g2, box2);
  const int n1 = i1->num_parts > 0 && !floor ? i1->num_parts : 1;
  const int n2 = i2->num_parts > 0 && !floor ? i2->num_parts : 1;
  for (int a = 0; a < n1; ++a) {
    if (a > 0 && !place_arm(i1->parts[a], b1, a - 1, box2)) continue;
    for (int b = 0; b < n2; ++b) {
      if (b > 0 && !place_arm(i2->parts[b], b2, b - 1, box1)) continue;
      add_contacts(ode, i1->num_parts > 0 ? i1->parts[a] : g1, b1, i2->num_parts > 0 ? i2->parts[b] : g2, b2);
    }
  }
}

}  // namespace hns::physics::world_detail
