#include "physics/world.hpp"

#include <ode/ode.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "physics/ode_runtime.hpp"
#include "physics/world_ode.hpp"

namespace hns::physics {
namespace {

// The ramp's wedge as ODE polygons: bottom, back, slope, left cap, right cap (world_ode.hpp has its points
// and planes).
unsigned int kRampPolygons[] = {4, 0, 3, 2, 1, 4, 0, 1, 5, 4, 4, 3, 4, 5, 2, 3, 0, 4, 3, 3, 1, 2, 5};

// Extra, deterministic work per env step in builds configured with HNS_INJECT_STEP_WORK > 0: the perf
// gate's tests use such a build as a known slowdown. A no-op otherwise.
#ifndef HNS_INJECT_STEP_WORK
#define HNS_INJECT_STEP_WORK 0
#endif
void inject_step_work() {
  if constexpr (HNS_INJECT_STEP_WORK > 0) {
    static volatile uint64_t sink = 0;
    uint64_t x = sink | 1;
    for (long i = 0; i < HNS_INJECT_STEP_WORK; ++i) {
      x ^= x << 13;
      x ^= x >> 7;
      x ^= x << 17;
    }
    sink = x;
  }
}

void set_yaw(dBodyID body, double yaw) {
  const dQuaternion q = {std::cos(0.5 * yaw), 0, 0, std::sin(0.5 * yaw)};
  dBodySetQuaternion(body, q);
}

}  // namespace

using namespace world_detail;

void check_field(bool ok, std::string_view field, double value, std::string_view allowed) {
  if (ok) return;
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, value);
  throw ConfigError(std::string(field) + " = " + std::string(buf, ec == std::errc() ? end : buf) +
                    " is invalid: " + std::string(allowed));
}

// The hide-and-seek game's worlds (world.hpp); the scenes built on them are batch/scenes.hpp's.
WorldConfig WorldConfig::quadrant() {
  WorldConfig c;
  c.scene = SceneConfig::quadrant();
  c.horizon = 80;
  c.lock_ramps = false;
  return c;
}

WorldConfig WorldConfig::full() {
  WorldConfig c;
  c.scene = SceneConfig::full();
  c.horizon = 240;
  c.lock_ramps = true;
  return c;
}

WorldConfig WorldConfig::empty() {
  WorldConfig c;
  c.scene = SceneConfig::empty();
  c.horizon = 80;
  c.lock_ramps = true;
  return c;
}

int WorldConfig::prep_steps() const {
  return int(std::ceil(prep_fraction * horizon - 1e-9));
}

void WorldConfig::validate() const {
  scene.validate();
  const auto check = check_field;
  check(horizon >= 1 && horizon <= 1000000, "horizon", horizon, "must be in [1, 1000000]");
  check(prep_fraction >= 0 && prep_fraction < 1, "prep_fraction", prep_fraction, "must be in [0, 1)");
  check(grab_radius > 0 && grab_radius <= 2, "grab_radius", grab_radius, "must be in (0, 2] m");
  check(grab_release_slack >= 0 && grab_release_slack <= 1, "grab_release_slack", grab_release_slack,
        "must be in [0, 1] m");
  check(lock_radius > 0 && lock_radius <= 2, "lock_radius", lock_radius, "must be in (0, 2] m");
  check(physics.step_time > 0 && physics.step_time <= 1, "physics.step_time", physics.step_time,
        "must be in (0, 1] s");
  check(physics.substeps >= 1 && physics.substeps <= 200, "physics.substeps", physics.substeps,
        "must be in [1, 200]");
  check(physics.solver_iterations >= 1 && physics.solver_iterations <= 1000, "physics.solver_iterations",
        physics.solver_iterations, "must be in [1, 1000]");
  check(std::isfinite(physics.gravity) && std::abs(physics.gravity) <= 1000, "physics.gravity",
        physics.gravity, "must be finite, |g| <= 1000 m/s²");
  check(physics.erp > 0 && physics.erp <= 1, "physics.erp", physics.erp, "must be in (0, 1]");
  check(physics.cfm >= 0 && physics.cfm <= 1, "physics.cfm", physics.cfm, "must be in [0, 1]");
  check(physics.contact_surface_layer >= 0 && physics.contact_surface_layer <= 0.05,
        "physics.contact_surface_layer", physics.contact_surface_layer, "must be in [0, 0.05] m");
  check(physics.max_correcting_vel > 0, "physics.max_correcting_vel", physics.max_correcting_vel,
        "must be > 0");
  check(physics.floor_cfm >= 0 && physics.floor_cfm <= 0.1, "physics.floor_cfm", physics.floor_cfm,
        "must be in [0, 0.1]");
  check(physics.slip_speed >= 0, "physics.slip_speed", physics.slip_speed, "must be >= 0 m/s (0: off)");
}

World::World(const WorldConfig& config, uint64_t seed, uint64_t world_index)
    : config_(config), seed_(seed), world_index_(world_index), ode_(std::make_unique<Ode>()) {
  config_.validate();
  ensure_ode_thread();
  Ode& o = *ode_;
  o.world = dWorldCreate();
  // Each world gets its own self-threaded implementation: with Debian's ODE (no TLS), worlds sharing the
  // default one abort when stepped from two threads at once (docs/design.md "Threading and ODE").
  o.threading = dThreadingAllocateSelfThreadedImplementation();
  dWorldSetStepThreadingImplementation(o.world, dThreadingImplementationGetFunctions(o.threading),
                                       o.threading);
  dWorldSetGravity(o.world, 0, 0, config_.physics.gravity);
  dWorldSetERP(o.world, config_.physics.erp);
  dWorldSetCFM(o.world, config_.physics.cfm);
  dWorldSetQuickStepNumIterations(o.world, config_.physics.solver_iterations);
  dWorldSetContactSurfaceLayer(o.world, config_.physics.contact_surface_layer);
  dWorldSetContactMaxCorrectingVel(o.world, config_.physics.max_correcting_vel);
  o.floor_cfm = config_.physics.floor_cfm;
  o.slip_speed = config_.physics.slip_speed;
  dWorldSetAutoDisableFlag(o.world, 0);
  o.dynamic_space = dSimpleSpaceCreate(nullptr);
  o.static_space = dSimpleSpaceCreate(nullptr);
  o.contacts = dJointGroupCreate(0);
  o.wall_info.friction =
      config_.scene.layout == Layout::kRandomWalls ? kRandomWallFriction : kQuadrantWallFriction;

  dGeomID floor = dCreatePlane(o.static_space, 0, 0, 1, 0);
  dGeomSetData(floor, &o.floor_info);

  // Bodies for the configured maxima; slots unused in an episode are disabled.
  const int max_agents = config_.max_agents();
  const int max_boxes = config_.scene.boxes.max;
  const int max_ramps = config_.scene.ramps.max;
  auto make_body = [&](dGeomID geom, GeomInfo* info, double yaw_inertia) {
    dBodyID body = dBodyCreate(o.world);
    dMass mass;
    dMassSetParameters(&mass, kBodyMass, 0, 0, 0, kLockedTiltInertia, kLockedTiltInertia, yaw_inertia, 0, 0,
                       0);
    dBodySetMass(body, &mass);
    dBodySetGyroscopicMode(body, 0);
    dGeomSetBody(geom, body);
    dGeomSetData(geom, info);
    dBodyDisable(body);
    dGeomDisable(geom);
    return body;
  };
  // Agents: the proxy in the space, then its parts outside it: the body sphere and the two massless arms
  // (docs/game.md §1.2).
  o.agent_proxy_info.assign(max_agents, GeomInfo{kAgentFriction});
  for (int i = 0; i < max_agents; ++i) {
    dGeomID proxy = dCreateSphere(o.dynamic_space, kAgentReach);
    o.agent_geoms.push_back(proxy);
    dBodyID body = make_body(proxy, &o.agent_proxy_info[i], kAgentYawInertia);
    o.agents.push_back(body);
    GeomInfo& proxy_info = o.agent_proxy_info[i];
    dGeomID main = dCreateSphere(nullptr, kAgentRadius);
    dGeomSetBody(main, body);
    dGeomSetData(main, &o.agent_info);
    proxy_info.parts[proxy_info.num_parts++] = main;
    for (int k = 0; k < 2; ++k) {
      dGeomID arm = dCreateSphere(nullptr, kArmRadius);  // bodyless: placed where it is collided
      dGeomSetData(arm, &o.agent_info);
      proxy_info.parts[proxy_info.num_parts++] = arm;
    }
    o.agent_parts.insert(o.agent_parts.end(), proxy_info.parts.begin(), proxy_info.parts.end());
  }

  // Boxes and ramps at rest fall asleep (leave the solver) until something touches them.
  auto allow_sleep = [&](dBodyID body) {
    if (!config_.physics.sleep) return body;
    dBodySetAutoDisableFlag(body, 1);
    dBodySetAutoDisableLinearThreshold(body, config_.physics.sleep_linear_speed);
    dBodySetAutoDisableAngularThreshold(body, config_.physics.sleep_angular_speed);
    dBodySetAutoDisableSteps(body, config_.physics.sleep_substeps);
    dBodySetAutoDisableTime(body, 0);
    return body;
  };
  for (int i = 0; i < max_boxes; ++i) {
    dGeomID g = dCreateBox(o.dynamic_space, kBoxSize, kBoxSize, kBoxSize);
    o.box_geoms.push_back(g);
    o.boxes.push_back(allow_sleep(make_body(g, &o.box_info, kBoxSize * kBoxSize / 6.0)));
  }
  o.box_mass.resize(max_boxes);
  for (int i = 0; i < max_ramps; ++i) {
    dGeomID g = dCreateConvex(o.dynamic_space, kRampPlanes, 5, kRampPoints, 6, kRampPolygons);
    o.ramp_geoms.push_back(g);
    o.ramps.push_back(allow_sleep(make_body(g, &o.ramp_info, kRampYawInertia)));
  }
  o.grab.assign(max_agents, nullptr);
  const int max_objects = max_boxes + max_ramps;
  locked_.assign(max_objects, 0);
  lock_team_.assign(max_objects, -1);
  locker_.assign(max_objects, -1);
  holding_.assign(max_agents, -1);
  visibility_.assign(size_t(max_agents) * max_objects, 0);
  forces_.assign(size_t(max_agents) * 3, 0.0);
  scratch_.assign(size_t(max_agents), 0);
}

World::~World() {
  Ode& o = *ode_;
  ensure_ode_thread();
  for (dJointID& j : o.grab) {
    if (j != nullptr) dJointDestroy(j);
  }
  dJointGroupDestroy(o.contacts);
  for (dGeomID g : o.agent_parts) dGeomDestroy(g);  // outside any space
  dSpaceDestroy(o.dynamic_space);                   // destroys its geoms
  dSpaceDestroy(o.static_space);
  dWorldSetStepThreadingImplementation(o.world, nullptr, nullptr);
  dThreadingFreeImplementation(o.threading);
  dWorldDestroy(o.world);  // destroys bodies and remaining joints
}

void World::reset(uint64_t episode) {
  episode_ = episode;
  rng_ = Rng(seed_, world_index_, episode);
  generate_scene(config_.scene, rng_, scene_);
  build_scene();
}

void World::reset_with_scene(const Scene& scene, uint64_t episode) {
  auto check = [](int count, int max, const char* what) {
    if (count > max) {
      std::ostringstream out;
      out << "scene has " << count << " " << what << " but the world was configured for at most " << max;
      throw ConfigError(out.str());
    }
  };
  check(scene.num_hiders + scene.num_seekers, config_.max_agents(), "agents");
  check(int(scene.boxes.size()), config_.scene.boxes.max, "boxes");
  check(int(scene.ramps.size()), config_.scene.ramps.max, "ramps");
  check(int(scene.sites.size()), config_.scene.sites.max, "construction sites");
  check(int(scene.food.size()), config_.scene.food.max, "food items");
  episode_ = episode;
  rng_ = Rng(seed_, world_index_, episode);
  scene_ = scene;
  build_scene();
}

void World::build_scene() {
  ensure_ode_thread();
  Ode& o = *ode_;
  for (int a = 0; a < int(o.grab.size()); ++a) release(a);
  dJointGroupEmpty(o.contacts);

  for (dGeomID g : o.walls) dGeomDestroy(g);
  o.walls.clear();
  for (const StaticBox& w : scene_.wall_boxes) {
    dGeomID g = dCreateBox(o.static_space, 2 * w.hx, 2 * w.hy, 2 * w.hz);
    dGeomSetPosition(g, w.cx, w.cy, w.cz);
    dGeomSetData(g, &o.wall_info);
    o.walls.push_back(g);
  }
  if (scene_.has_target) {  // shelter's cylinder: static, along z, as slippery as the walls
    const Spawn& t = scene_.target;
    dGeomID g = dCreateCylinder(o.static_space, 0.5 * t.sx, t.sz);
    dGeomSetPosition(g, t.x, t.y, t.z);
    dGeomSetData(g, &o.wall_info);
    o.walls.push_back(g);
  }

  // ODE keeps history in reused bodies and geoms that would make an episode depend on the ones before it
  // (and a resumed run differ from an uninterrupted one): the simple space's geom order, which decides the
  // order of contacts and so the solver's arithmetic (a moved geom that was clean jumps to the front: which
  // ones were clean depends on what slept or was locked when the last episode ended), the velocity samples
  // of the auto-disable average, and the force accumulators. All are put back to what a new world has.
  auto restore_order = [&](const std::vector<dGeomID>& geoms) {
    for (dGeomID g : geoms) {
      dSpaceRemove(o.dynamic_space, g);
      dSpaceAdd(o.dynamic_space, g);
    }
  };
  restore_order(o.agent_geoms);
  restore_order(o.box_geoms);
  restore_order(o.ramp_geoms);
  auto place = [](dBodyID body, dGeomID geom, bool active, double x, double y, double z) {
    dBodySetAutoDisableAverageSamplesCount(body, dBodyGetAutoDisableAverageSamplesCount(body));
    dBodySetForce(body, 0, 0, 0);
    dBodySetTorque(body, 0, 0, 0);
    dBodySetDynamic(body);
    dBodySetPosition(body, x, y, z);
    set_yaw(body, 0.0);
    dBodySetLinearVel(body, 0, 0, 0);
    dBodySetAngularVel(body, 0, 0, 0);
    if (active) {
      dBodyEnable(body);
      dGeomEnable(geom);
    } else {
      dBodyDisable(body);
      dGeomDisable(geom);
    }
  };
  // Unused slots park far below the floor, disabled.
  for (int i = 0; i < int(o.agents.size()); ++i) {
    const bool active = i < num_agents();
    const Spawn s = active ? scene_.agents[i] : Spawn{0, 0, -50.0 - i, 0, 0, 0};
    place(o.agents[i], o.agent_geoms[i], active, s.x, s.y, s.z);
  }
  for (int i = 0; i < int(o.boxes.size()); ++i) {
    const bool active = i < num_boxes();
    const Spawn s = active ? scene_.boxes[i] : Spawn{0, 0, -60.0 - i, kBoxSize, kBoxSize, kBoxSize};
    dGeomBoxSetLengths(o.box_geoms[i], s.sx, s.sy, s.sz);
    dMassSetParameters(&o.box_mass[i], kBodyMass, 0, 0, 0, kLockedTiltInertia, kLockedTiltInertia,
                       kBodyMass * (s.sx * s.sx + s.sy * s.sy) / 12.0, 0, 0, 0);
    place(o.boxes[i], o.box_geoms[i], active, s.x, s.y, s.z);
    dBodySetMass(o.boxes[i], &o.box_mass[i]);
  }
  for (int i = 0; i < int(o.ramps.size()); ++i) {
    const bool active = i < num_ramps();
    const Spawn s = active ? scene_.ramps[i] : Spawn{0, 0, -70.0 - i, 0, 0, 0};
    place(o.ramps[i], o.ramp_geoms[i], active, s.x, s.y + kRampCentroidY, s.z + kRampCentroidZ);
  }

  std::fill(locked_.begin(), locked_.end(), 0);
  std::fill(lock_team_.begin(), lock_team_.end(), -1);
  std::fill(locker_.begin(), locker_.end(), -1);
  std::fill(holding_.begin(), holding_.end(), -1);
  t_ = 0;
  prep_steps_ = config_.prep_steps();
  unstable_ = false;
  std::fill(visibility_.begin(), visibility_.end(), 0);
  if (config_.compute_visibility) update_visibility();
}

void World::step(std::span<const AgentAction> actions) {
  if (int(actions.size()) != num_agents()) {
    throw std::invalid_argument("World::step: got " + std::to_string(actions.size()) + " actions for " +
                                std::to_string(num_agents()) + " agents");
  }
  ensure_ode_thread();
  ScopedSolverRng solver_rng(rng_);
  // Seekers are powerless during the preparation phase (docs/game.md §3.5): their action is the zero action.
  const bool prep = t_ < prep_steps_;
  AgentAction effective_storage[64];
  std::vector<AgentAction> effective_heap;
  AgentAction* effective = effective_storage;
  if (actions.size() > std::size(effective_storage)) {
    effective_heap.resize(actions.size());
    effective = effective_heap.data();
  }
  for (int a = 0; a < num_agents(); ++a) {
    effective[a] = (prep && team(a) == Team::kSeeker) ? AgentAction{} : actions[a];
  }
  const std::span<const AgentAction> acts(effective, actions.size());

  apply_grab(acts);
  apply_lock(acts);
  for (int a = 0; a < num_agents(); ++a) {
    const AgentAction& act = acts[a];
    forces_[3 * a + 0] = kGear * bin_control(std::min<int>(act.move_x, kMoveBins - 1));
    forces_[3 * a + 1] = kGear * bin_control(std::min<int>(act.move_y, kMoveBins - 1));
    forces_[3 * a + 2] = kGear * bin_control(std::min<int>(act.turn, kMoveBins - 1));
  }
  for (int s = 0; s < config_.physics.substeps; ++s) substep(forces_);
  ++t_;
  inject_step_work();
  check_stability();
  if (config_.compute_visibility) update_visibility();
}

void World::substep(std::span<const double> forces) {
  Ode& o = *ode_;
  const double dt = config_.physics.step_time / config_.physics.substeps;
  // Joint damping as a force the solver sees, sized as MuJoCo's implicit Euler damping would act:
  // F_d = -c·(m·v + F·dt)/(m + c·dt), with m the mass (or yaw inertia) that moves with the body. Unlike
  // explicit damping it stays stable for the agent's tiny yaw inertia (c·dt/I ≈ 8); unlike rescaling the
  // velocity after the step it keeps grab joints tight.
  auto damp = [dt](dBodyID body, double fx, double fy, double tz, double damp_xy, double damp_z,
                   double damp_yaw, double mass, double yaw_inertia) {
    // A sleeping body is left alone: ODE clears a body's force accumulators only when it steps it, so forces
    // added while it sleeps would pile up and strike at once when it wakes.
    if (dBodyIsKinematic(body) || !dBodyIsEnabled(body)) return;
    const dReal* v = dBodyGetLinearVel(body);
    const dReal* w = dBodyGetAngularVel(body);
    const double kxy = damp_xy / (mass + damp_xy * dt);
    const double kz = damp_z / (mass + damp_z * dt);
    dBodyAddForce(body, fx - kxy * (mass * v[0] + fx * dt), fy - kxy * (mass * v[1] + fy * dt),
                  -kz * mass * v[2]);
    const double kyaw = damp_yaw / (yaw_inertia + damp_yaw * dt);
    dBodyAddTorque(body, 0, 0, tz - kyaw * (yaw_inertia * w[2] + tz * dt));
  };
  for (int a = 0; a < num_agents(); ++a) {
    // An agent holding an object moves it too: its damping sees the pair's mass and yaw inertia.
    double mass = kBodyMass, yaw_inertia = kAgentYawInertia;
    if (holding_[a] >= 0) {
      dBodyID held = o.object_body(holding_[a], num_boxes());
      const dReal* pa = dBodyGetPosition(o.agents[a]);
      const dReal* ph = dBodyGetPosition(held);
      const double d2 = (pa[0] - ph[0]) * (pa[0] - ph[0]) + (pa[1] - ph[1]) * (pa[1] - ph[1]);
      dMass held_mass;
      dBodyGetMass(held, &held_mass);
      mass += kBodyMass;
      yaw_inertia += held_mass.I[2 * 4 + 2] + kBodyMass * d2;
    }
    damp(o.agents[a], forces[3 * a], forces[3 * a + 1], forces[3 * a + 2], kAgentDampXY, kAgentDampZ,
         kAgentDampYaw, mass, yaw_inertia);
  }
  for (int b = 0; b < num_boxes(); ++b) {
    damp(o.boxes[b], 0, 0, 0, kBoxDamp, kBoxDamp, kBoxDamp, kBodyMass, o.box_mass[b].I[2 * 4 + 2]);
  }
  for (int r = 0; r < num_ramps(); ++r) {
    damp(o.ramps[r], 0, 0, 0, kRampDamp, kRampDamp, kRampDamp, kBodyMass, kRampYawInertia);
  }

  dSpaceCollide(o.dynamic_space, &o, near_callback);
  dSpaceCollide2(reinterpret_cast<dGeomID>(o.dynamic_space), reinterpret_cast<dGeomID>(o.static_space), &o,
                 near_callback);
  dWorldQuickStep(o.world, dt);
  dJointGroupEmpty(o.contacts);

  // Keep every body rotating about z only: drop the tilt that contact torques left.
  auto keep_yaw_only = [](dBodyID body) {
    if (dBodyIsKinematic(body) || !dBodyIsEnabled(body)) return;
    const dReal* w = dBodyGetAngularVel(body);
    dBodySetAngularVel(body, 0, 0, w[2]);
    const dReal* q = dBodyGetQuaternion(body);
    const double norm = std::sqrt(q[0] * q[0] + q[3] * q[3]);
    const dQuaternion yaw_only = {q[0] / norm, 0, 0, q[3] / norm};
    dBodySetQuaternion(body, yaw_only);
  };
  for (int a = 0; a < num_agents(); ++a) keep_yaw_only(o.agents[a]);
  for (int b = 0; b < num_boxes(); ++b) keep_yaw_only(o.boxes[b]);
  for (int r = 0; r < num_ramps(); ++r) keep_yaw_only(o.ramps[r]);
}

void World::check_stability() {
  auto sane = [](dBodyID body) {
    const dReal* p = dBodyGetPosition(body);
    const dReal* v = dBodyGetLinearVel(body);
    for (int i = 0; i < 3; ++i) {
      if (!std::isfinite(p[i]) || !std::isfinite(v[i]) || std::abs(v[i]) > kSaneSpeed) return false;
    }
    return std::abs(p[0]) < kSaneXY && std::abs(p[1]) < kSaneXY && std::abs(p[2]) < kSaneZ;
  };
  const Ode& o = *ode_;
  for (int a = 0; a < num_agents(); ++a) unstable_ = unstable_ || !sane(o.agents[a]);
  for (int b = 0; b < num_boxes(); ++b) unstable_ = unstable_ || !sane(o.boxes[b]);
  for (int r = 0; r < num_ramps(); ++r) unstable_ = unstable_ || !sane(o.ramps[r]);
}

namespace {
BodyState read_body(dBodyID body) {
  BodyState s;
  const dReal* p = dBodyGetPosition(body);
  const dReal* v = dBodyGetLinearVel(body);
  const dReal* w = dBodyGetAngularVel(body);
  for (int i = 0; i < 3; ++i) {
    s.pos[i] = p[i];
    s.vel[i] = v[i];
  }
  // A yaw-only quaternion (w, 0, 0, z) rotates by 2·atan2(z, w): cos = (w² - z²)/n, sin = 2wz/n, n = w² + z².
  const dReal* q = dBodyGetQuaternion(body);
  const double n = q[0] * q[0] + q[3] * q[3];
  s.cos_yaw = (q[0] * q[0] - q[3] * q[3]) / n;
  s.sin_yaw = 2.0 * q[0] * q[3] / n;
  s.ang_vel = w[2];
  return s;
}
}  // namespace

BodyState World::agent_state(int agent) const {
  return read_body(ode_->agents[agent]);
}
BodyState World::box_state(int box) const {
  return read_body(ode_->boxes[box]);
}

BodyState World::ramp_state(int ramp) const {
  BodyState s = read_body(ode_->ramps[ramp]);
  // Body origin is the wedge centroid; report the bounding-box centre.
  const double c = s.cos_yaw, sn = s.sin_yaw;
  s.pos[0] += sn * kRampCentroidY;
  s.pos[1] -= c * kRampCentroidY;
  s.pos[2] -= kRampCentroidZ;
  return s;
}

namespace {
void move_body(dBodyID body, double x, double y, double z, double yaw) {
  dBodyEnable(body);
  dBodySetPosition(body, x, y, z);
  set_yaw(body, yaw);
  dBodySetLinearVel(body, 0, 0, 0);
  dBodySetAngularVel(body, 0, 0, 0);
}
}  // namespace

void World::set_agent_pose(int agent, double x, double y, double z, double yaw) {
  move_body(ode_->agents[agent], x, y, z, yaw);
}
void World::set_box_pose(int box, double x, double y, double z, double yaw) {
  move_body(ode_->boxes[box], x, y, z, yaw);
}
void World::set_ramp_pose(int ramp, double x, double y, double z, double yaw) {
  const double c = std::cos(yaw), s = std::sin(yaw);
  move_body(ode_->ramps[ramp], x - s * kRampCentroidY, y + c * kRampCentroidY, z + kRampCentroidZ, yaw);
}

Occluders World::occluders() {
  occ_walls_.clear();
  for (const StaticBox& w : scene_.wall_boxes)
    occ_walls_.push_back({w.cx, w.cy, w.cz, w.hx, w.hy, w.hz, 1, 0});
  occ_boxes_.clear();
  for (int b = 0; b < num_boxes(); ++b) {
    const BodyState s = box_state(b);
    const Spawn& sz = scene_.boxes[b];
    occ_boxes_.push_back(
        {s.pos[0], s.pos[1], s.pos[2], 0.5 * sz.sx, 0.5 * sz.sy, 0.5 * sz.sz, s.cos_yaw, s.sin_yaw});
  }
  occ_ramps_.clear();
  for (int r = 0; r < num_ramps(); ++r) {
    const BodyState s = ramp_state(r);
    occ_ramps_.push_back({s.pos[0], s.pos[1], s.pos[2], s.cos_yaw, s.sin_yaw});
  }
  occ_agents_.clear();
  occ_arms_.clear();
  for (int a = 0; a < num_agents(); ++a) {
    const BodyState s = agent_state(a);
    occ_agents_.push_back({s.pos[0], s.pos[1], s.pos[2], kAgentRadius});
    double arms[2][3];
    arm_centres(s.pos, s.cos_yaw, s.sin_yaw, arms);
    for (const auto& arm : arms) occ_arms_.push_back({arm[0], arm[1], arm[2], kArmRadius});
  }
  occ_cylinders_.clear();
  if (scene_.has_target) {
    const Spawn& t = scene_.target;
    occ_cylinders_.push_back({t.x, t.y, 0.5 * t.sx, t.sz});
  }
  return Occluders{occ_walls_, occ_boxes_, occ_ramps_, occ_agents_, occ_arms_, occ_cylinders_};
}

void World::update_visibility() {
  const Occluders occ = occluders();
  const int n_obj = num_objects();
  for (int a = 0; a < num_agents(); ++a) {
    const BodyState st = agent_state(a);
    const double c = st.cos_yaw, s = st.sin_yaw;
    for (int obj = 0; obj < n_obj; ++obj) {
      const bool is_box = obj < num_boxes();
      visibility_[size_t(a) * n_obj + obj] =
          visible(occ, a, c, s, is_box ? HitKind::kBox : HitKind::kRamp, is_box ? obj : obj - num_boxes())
              ? 1
              : 0;
    }
  }
}

}  // namespace hns::physics
