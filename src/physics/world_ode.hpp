// What World's source files share (world.cpp: config, bodies, stepping, state; world_contacts.cpp: the
// contacts; world_grab_lock.cpp: grab and lock): the ODE handles (World::Ode), the bodies' constants, the
// ramp's convex and the geoms' user data. Private to src/physics.
#pragma once

#include <ode/ode.h>

#include <array>
#include <vector>

#include "physics/sphere_convex.hpp"
#include "physics/world.hpp"

namespace hns::physics {
namespace world_detail {

inline constexpr int kMaxContactsPerPair = 8;

// Body constants (docs/game.md §1.2). Rotation about x and y is removed by a huge inertia on those axes plus
// a projection back to pure yaw after every substep, which together act like the original's missing hinges.
inline constexpr double kBodyMass = 1.0;                       // kg, agents, boxes and ramps alike
inline constexpr double kLockedTiltInertia = 1e4;              // kg·m², x/y inertia of every movable body
inline constexpr double kAgentYawInertia = 0.4 * 0.15 * 0.15;  // kg·m², solid sphere r = 0.15
inline constexpr double kAgentDampXY = 10.0;                   // N·s/m (joint damping of tx, ty)
inline constexpr double kAgentDampZ = 1.0;                     // N·s/m (tz, overridden to 1 in the original)
inline constexpr double kAgentDampYaw = 10.0;                  // N·m·s (rz)
inline constexpr double kBoxDamp = 0.01;                       // every box joint
inline constexpr double kRampDamp = 0.1;                       // every ramp joint
inline constexpr double kAgentFriction = 0.01;
inline constexpr double kBoxFriction = 0.2;
inline constexpr double kRampFriction = 0.01;
inline constexpr double kFloorFriction = 0.2;
inline constexpr double kQuadrantWallFriction = 0.01;
inline constexpr double kRandomWallFriction = 1.0;  // RandomWalls passes no friction: MuJoCo's default
// Wedge yaw inertia about its centroid: m·(a²/12 + Var_y(triangle)) with a = 0.5.
inline constexpr double kRampYawInertia = 0.5 * 0.5 / 12.0 + 0.25 / 18.0;
// Bodies outside these bounds (or non-finite) make the world unstable.
inline constexpr double kSaneXY = 200.0, kSaneZ = 100.0, kSaneSpeed = 200.0;

// The wedge as an ODE convex, relative to its centroid. Faces: bottom, back, slope, left cap, right cap.
inline constexpr double kH = kRampHalf;
inline constexpr double kRampPoints[18] = {
    -kH, -kH - kRampCentroidY, -kH - kRampCentroidZ, kH,  -kH - kRampCentroidY, -kH - kRampCentroidZ,
    kH,  kH - kRampCentroidY,  -kH - kRampCentroidZ, -kH, kH - kRampCentroidY,  -kH - kRampCentroidZ,
    -kH, -kH - kRampCentroidY, kH - kRampCentroidZ,  kH,  -kH - kRampCentroidY, kH - kRampCentroidZ,
};
inline constexpr double kInvSqrt2 = 0.70710678118654752440;
inline constexpr double kRampPlanes[20] = {
    0,  0,         -1,        kH + kRampCentroidZ,                             // bottom
    0,  -1,        0,         kH + kRampCentroidY,                             // back
    0,  kInvSqrt2, kInvSqrt2, -(kRampCentroidY + kRampCentroidZ) * kInvSqrt2,  // slope y + z <= 0
    -1, 0,         0,         kH,                                              // left cap
    1,  0,         0,         kH,                                              // right cap
};
inline constexpr int kRampEdges[18] = {0, 1, 1, 2, 2, 3, 3, 0, 0, 4, 1, 5, 4, 5, 3, 4, 2, 5};
inline const ConvexShape kRampShape{kRampPlanes, kRampPoints, kRampEdges};

// A geom's ODE user data: its friction, and for an agent's broad-phase proxy the geoms that really collide
// (its body sphere and two arms).
struct GeomInfo {
  double friction;
  std::array<dGeomID, 3> parts{};  // body sphere first
  int num_parts = 0;
};

// ODE near callback for a pair whose bounding boxes overlap (world_contacts.cpp); `data` is the World::Ode.
void near_callback(void* data, dGeomID g1, dGeomID g2);

}  // namespace world_detail

struct World::Ode {
  dWorldID world = nullptr;
  dSpaceID dynamic_space = nullptr;  // agents, boxes, ramps
  dSpaceID static_space = nullptr;   // floor and walls
  dJointGroupID contacts = nullptr;
  dThreadingImplementationID threading = nullptr;
  std::vector<dBodyID> agents, boxes, ramps;
  // An agent is a broad-phase proxy in the dynamic space (a sphere holding body and arms, never collided
  // itself) whose parts, outside any space, are collided only when the proxy overlaps something. The body
  // sphere is fixed to the agent's body; the arms have none and are placed from its pose when collided, so
  // they cost nothing while the agent is clear of everything.
  std::vector<dGeomID> agent_geoms, box_geoms, ramp_geoms, walls;
  std::vector<dGeomID> agent_parts;                      // three per agent: body sphere, left arm, right arm
  std::vector<world_detail::GeomInfo> agent_proxy_info;  // per agent: its parts
  std::vector<dMass> box_mass;
  std::vector<dJointID> grab;  // per agent, nullptr = none
  world_detail::GeomInfo agent_info{world_detail::kAgentFriction}, box_info{world_detail::kBoxFriction};
  world_detail::GeomInfo ramp_info{world_detail::kRampFriction}, floor_info{world_detail::kFloorFriction},
      wall_info{world_detail::kQuadrantWallFriction};
  double floor_cfm = 0;   // PhysicsConfig::floor_cfm
  double slip_speed = 0;  // PhysicsConfig::slip_speed

  // Object o of an episode with `num_boxes` boxes: boxes first, then ramps (the slot vectors hold the
  // maxima, so a ramp's slot does not follow the last box slot).
  dBodyID object_body(int object, int num_boxes) const {
    return object < num_boxes ? boxes[object] : ramps[object - num_boxes];
  }
};

}  // namespace hns::physics
