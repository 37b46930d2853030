// World's grab and lock (docs/game.md §3.3, §3.4, §14.2).
#include <ode/ode.h>

#include <algorithm>
#include <cmath>

#include "physics/world_ode.hpp"

namespace hns::physics {

using namespace world_detail;

double World::agent_object_distance(int agent, int object) const {
  const BodyState a = agent_state(agent);
  OrientedBox box;
  if (object < num_boxes()) {
    const BodyState b = box_state(object);
    const Spawn& s = scene_.boxes[object];
    box = OrientedBox{b.pos[0], b.pos[1], b.pos[2], 0.5 * s.sx, 0.5 * s.sy, 0.5 * s.sz, b.cos_yaw, b.sin_yaw};
  } else {
    const BodyState r = ramp_state(object - num_boxes());
    box = ramp_reach_box(Wedge{r.pos[0], r.pos[1], r.pos[2], r.cos_yaw, r.sin_yaw});
  }
  return distance_to_box(a.pos, box);
}

void World::release(int agent) {
  dJointID& joint = ode_->grab[agent];
  if (joint != nullptr) {
    dJointDestroy(joint);
    joint = nullptr;
  }
  holding_[agent] = -1;
}

// Grab (docs/game.md §3.3, §14.2): each agent pressing grab holds the closest object that it saw in the last
// observation and that lies within the grab radius (plus a slack for the object it already holds). The
// object keeps its pose relative to the agent through an ODE fixed joint.
void World::apply_grab(std::span<const AgentAction> actions) {
  Ode& o = *ode_;
  const int n_obj = num_objects();
  for (int a = 0; a < num_agents(); ++a) {
    int target = -1;
    if (actions[a].grab != 0) {
      double best = 1e30;
      for (int obj = 0; obj < n_obj; ++obj) {
        if (visibility_[size_t(a) * n_obj + obj] == 0) continue;
        const double d = agent_object_distance(a, obj);
        const double limit = config_.grab_radius + (holding_[a] == obj ? config_.grab_release_slack : 0.0);
        if (d <= limit && d < best) {
          best = d;
          target = obj;
        }
      }
    }
    if (target == holding_[a]) continue;
    release(a);
    if (target >= 0) {
      dJointID joint = dJointCreateFixed(o.world, nullptr);
      dBodyEnable(o.object_body(target, num_boxes()));  // a sleeping object wakes when grabbed
      dJointAttach(joint, o.agents[a], o.object_body(target, num_boxes()));
      dJointSetFixed(joint);
      o.grab[a] = joint;
      holding_[a] = target;
    }
  }
}

// Lock (docs/game.md §3.4 'all_lock_team_specific', §14.3): an object in range and in view of an agent
// pressing lock gets pinned, unless a member of the team that locked it last stands in range, sees it and
// does not press lock: that unlocks it. A never-locked object has no owner, so nobody vetoes its first lock.
void World::apply_lock(std::span<const AgentAction> actions) {
  const int n_obj = num_objects();
  const int first = config_.lock_ramps ? n_obj - 1 : num_boxes() - 1;
  // Ramps first, then boxes (the original's wrapper order).
  // Sequential lock: lock requests for boxes after the first unlocked one (as this step starts) are masked,
  // as if the agent did not press lock.
  int next_in_order = num_boxes();
  if (config_.lock_in_order) {
    for (int b = num_boxes() - 1; b >= 0; --b) {
      if (locked_[b] == 0) next_in_order = b;
    }
  }
  for (int obj = first; obj >= 0; --obj) {
    int desiring = 0;
    bool unlock = false;
    const bool masked = obj < num_boxes() && obj > next_in_order;
    for (int a = 0; a < num_agents(); ++a) {
      scratch_[a] = 0;
      if (visibility_[size_t(a) * n_obj + obj] == 0) continue;
      if (agent_object_distance(a, obj) > config_.lock_radius) continue;
      if (actions[a].lock != 0 && !masked) {
        scratch_[a] = 1;
        ++desiring;
      } else if (lock_team_[obj] >= 0 && int(team(a)) == lock_team_[obj]) {
        unlock = true;
      }
    }
    const bool lock = desiring > 0 && !unlock;
    if (lock && locked_[obj] == 0) {
      // A new lock: the owner is one of the desiring agents, drawn from the world's stream.
      int pick = rng_.uniform_int(0, desiring);
      for (int a = 0; a < num_agents(); ++a) {
        if (scratch_[a] != 0 && pick-- == 0) {
          locker_[obj] = int8_t(a);
          lock_team_[obj] = int8_t(team(a));
          break;
        }
      }
    }
    const bool now_locked = (locked_[obj] != 0 && !unlock) || lock;
    if (now_locked != (locked_[obj] != 0)) set_locked(obj, now_locked);
  }
}

void World::set_locked(int object, bool locked) {
  Ode& o = *ode_;
  dBodyID body = o.object_body(object, num_boxes());
  if (locked) {
    dBodySetKinematic(body);
    dBodySetLinearVel(body, 0, 0, 0);
    dBodySetAngularVel(body, 0, 0, 0);
  } else {
    dBodySetDynamic(body);
    dBodyEnable(body);
    if (object < num_boxes()) {
      dBodySetMass(body, &o.box_mass[object]);
    } else {
      dMass mass;
      dMassSetParameters(&mass, kBodyMass, 0, 0, 0, kLockedTiltInertia, kLockedTiltInertia, kRampYawInertia,
                         0, 0, 0);
      dBodySetMass(body, &mass);
    }
  }
  locked_[object] = locked ? 1 : 0;
}

}  // namespace hns::physics
