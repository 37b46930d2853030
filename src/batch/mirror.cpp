// The mirror: after each step, an env's bodies are read back from its world into the SoA fields of the batch
// state (docs/game.md §14.1: true centres, yaw as (cos, sin)), and the ray casts' shapes are placed from it.
// Walls and the shelter's cylinder never move: their shapes are written once per episode.
#include <algorithm>

#include "batch/env.hpp"

namespace hns::batch {
namespace {

constexpr float kAgentRadius = float(physics::kAgentRadius);
constexpr float kArmRadius = float(physics::kArmRadius);
// Every arm lies within this distance of its agent's centre, with 1.8 mm to spare (far above rounding).
constexpr float kAgentReach = float(physics::kAgentReach);

// Copies the first `active` of `slots` bodies (get(i) -> BodyState) into SoA fields; later slots are zeroed.
template <class Get>
void copy_bodies(int slots, int active, Get&& get, float* pos, float* rot, float* vel, float* angvel) {
  for (int i = 0; i < slots; ++i) {
    const physics::BodyState b = i < active ? get(i) : physics::BodyState{};
    for (int k = 0; k < 3; ++k) {
      pos[3 * i + k] = float(b.pos[k]);
      vel[3 * i + k] = float(b.vel[k]);
    }
    rot[2 * i] = float(b.cos_yaw);
    rot[2 * i + 1] = float(b.sin_yaw);
    angvel[i] = float(b.ang_vel);
  }
}

}  // namespace

void mirror(EnvRef& ref) {
  const int env = ref.index;
  const physics::World& world = ref.world;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const size_t a0 = size_t(env) * L.max_agents, b0 = size_t(env) * L.max_boxes,
               r0 = size_t(env) * L.max_ramps;
  copy_bodies(
      L.max_agents, world.num_agents(), [&](int i) { return world.agent_state(i); },
      s.agent_pos.data() + (3 * a0), s.agent_rot.data() + (2 * a0), s.agent_vel.data() + (3 * a0),
      s.agent_angvel.data() + a0);
  copy_bodies(
      L.max_boxes, world.num_boxes(), [&](int i) { return world.box_state(i); }, s.box_pos.data() + (3 * b0),
      s.box_rot.data() + (2 * b0), s.box_vel.data() + (3 * b0), s.box_angvel.data() + b0);
  copy_bodies(
      L.max_ramps, world.num_ramps(), [&](int i) { return world.ramp_state(i); },
      s.ramp_pos.data() + (3 * r0), s.ramp_rot.data() + (2 * r0), s.ramp_vel.data() + (3 * r0),
      s.ramp_angvel.data() + r0);
  for (int a = 0; a < L.max_agents; ++a) {
    const bool exists = a < world.num_agents();
    s.agent_exists[a0 + a] = exists ? 1 : 0;
    s.agent_hider[a0 + a] = exists && world.team(a) == physics::Team::kHider ? 1 : 0;
  }
  const physics::Scene& scene = world.scene();
  for (int b = 0; b < L.max_boxes; ++b) {
    const bool exists = b < world.num_boxes();
    s.box_exists[b0 + b] = exists ? 1 : 0;
    s.box_locked[b0 + b] = exists && world.object_locked(b) ? 1 : 0;
    s.box_locker[b0 + b] = int8_t(exists ? world.object_locker(b) : -1);
    s.box_size[3 * (b0 + b) + 0] = exists ? float(scene.boxes[b].sx) : 0.0f;
    s.box_size[3 * (b0 + b) + 1] = exists ? float(scene.boxes[b].sy) : 0.0f;
    s.box_size[3 * (b0 + b) + 2] = exists ? float(scene.boxes[b].sz) : 0.0f;
  }
  for (int r = 0; r < L.max_ramps; ++r) {
    const bool exists = r < world.num_ramps();
    const int object = world.num_boxes() + r;
    s.ramp_exists[r0 + r] = exists ? 1 : 0;
    s.ramp_locked[r0 + r] = exists && world.object_locked(object) ? 1 : 0;
    s.ramp_locker[r0 + r] = int8_t(exists ? world.object_locker(object) : -1);
  }
}

void build_static_shapes(EnvRef& ref) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const physics::Scene& scene = ref.world.scene();
  const size_t sb = size_t(env) * L.shape_boxes;
  for (int w = 0; w < int(scene.wall_boxes.size()); ++w) {
    const physics::StaticBox& b = scene.wall_boxes[w];
    s.shape_box_cx[sb + w] = float(b.cx);
    s.shape_box_cy[sb + w] = float(b.cy);
    s.shape_box_cz[sb + w] = float(b.cz);
    s.shape_box_hx[sb + w] = float(b.hx);
    s.shape_box_hy[sb + w] = float(b.hy);
    s.shape_box_hz[sb + w] = float(b.hz);
    s.shape_box_c[sb + w] = 1.0f;
    s.shape_box_s[sb + w] = 0.0f;
  }
  if (L.shape_cylinders > 0) {
    const physics::Spawn& t = scene.target;
    s.shape_cyl_cx[env] = scene.has_target ? float(t.x) : 0.0f;
    s.shape_cyl_cy[env] = scene.has_target ? float(t.y) : 0.0f;
    s.shape_cyl_r[env] = scene.has_target ? float(0.5 * t.sx) : 0.0f;
    s.shape_cyl_h[env] = scene.has_target ? float(t.sz) : 0.0f;
  }
}

void build_shapes(EnvRef& ref) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const int walls = s.num_walls[env];
  const size_t sb = size_t(env) * L.shape_boxes;
  for (int k = walls; k < L.shape_boxes; ++k) {
    const int b = k - walls;
    const size_t i = size_t(env) * L.max_boxes + b;
    const bool exists = b < L.max_boxes && s.box_exists[i] != 0;
    s.shape_box_cx[sb + k] = exists ? s.box_pos[3 * i] : 0.0f;
    s.shape_box_cy[sb + k] = exists ? s.box_pos[3 * i + 1] : 0.0f;
    s.shape_box_cz[sb + k] = exists ? s.box_pos[3 * i + 2] : kParkedZ;
    s.shape_box_hx[sb + k] = exists ? 0.5f * s.box_size[3 * i] : 0.01f;
    s.shape_box_hy[sb + k] = exists ? 0.5f * s.box_size[3 * i + 1] : 0.01f;
    s.shape_box_hz[sb + k] = exists ? 0.5f * s.box_size[3 * i + 2] : 0.01f;
    s.shape_box_c[sb + k] = exists ? s.box_rot[2 * i] : 1.0f;
    s.shape_box_s[sb + k] = exists ? s.box_rot[2 * i + 1] : 0.0f;
  }
  const size_t sw = size_t(env) * L.shape_wedges;
  for (int k = 0; k < L.shape_wedges; ++k) {
    const size_t i = size_t(env) * L.max_ramps + k;
    const bool exists = k < L.max_ramps && s.ramp_exists[i] != 0;
    s.shape_wedge_cx[sw + k] = exists ? s.ramp_pos[3 * i] : 0.0f;
    s.shape_wedge_cy[sw + k] = exists ? s.ramp_pos[3 * i + 1] : 0.0f;
    s.shape_wedge_cz[sw + k] = exists ? s.ramp_pos[3 * i + 2] : kParkedZ;
    s.shape_wedge_c[sw + k] = exists ? s.ramp_rot[2 * i] : 1.0f;
    s.shape_wedge_s[sw + k] = exists ? s.ramp_rot[2 * i + 1] : 0.0f;
  }
  // Per agent: its body sphere, then its two arms (docs/game.md §1.2), placed by the agent's yaw.
  const size_t ss = size_t(env) * L.shape_spheres;
  for (int a = 0; a < L.max_agents; ++a) {
    const size_t i = size_t(env) * L.max_agents + a;
    const bool exists = s.agent_exists[i] != 0;
    float arms[2][3];
    physics::arm_centres(s.agent_pos.data() + (3 * i), s.agent_rot[2 * i], s.agent_rot[2 * i + 1], arms);
    const float* centres[Layout::kSpheresPerAgent] = {s.agent_pos.data() + (3 * i), arms[0], arms[1]};
    for (int k = 0; k < Layout::kSpheresPerAgent; ++k) {
      const size_t slot = ss + size_t(a) * Layout::kSpheresPerAgent + k;
      s.shape_sphere_cx[slot] = exists ? centres[k][0] : 0.0f;
      s.shape_sphere_cy[slot] = exists ? centres[k][1] : 0.0f;
      s.shape_sphere_cz[slot] = exists ? centres[k][2] : kParkedZ;
      s.shape_sphere_r[slot] = !exists ? 0.01f : k == 0 ? kAgentRadius : kArmRadius;
    }
  }
}

ShapesView shapes_view(const Layout& L, const BatchState& s, const physics::World& world, int env) {
  const size_t b = size_t(env) * L.shape_boxes, w = size_t(env) * L.shape_wedges;
  const size_t p = size_t(env) * L.shape_spheres;
  ShapesView v;
  v.box_cx = s.shape_box_cx.data() + b, v.box_cy = s.shape_box_cy.data() + b;
  v.box_cz = s.shape_box_cz.data() + b, v.box_hx = s.shape_box_hx.data() + b;
  v.box_hy = s.shape_box_hy.data() + b, v.box_hz = s.shape_box_hz.data() + b;
  v.box_c = s.shape_box_c.data() + b, v.box_s = s.shape_box_s.data() + b;
  v.num_boxes = L.shape_boxes, v.live_boxes = s.num_walls[env] + world.num_boxes();
  v.wedge_cx = s.shape_wedge_cx.data() + w, v.wedge_cy = s.shape_wedge_cy.data() + w;
  v.wedge_cz = s.shape_wedge_cz.data() + w, v.wedge_c = s.shape_wedge_c.data() + w;
  v.wedge_s = s.shape_wedge_s.data() + w;
  v.num_wedges = L.shape_wedges, v.live_wedges = world.num_ramps();
  v.sphere_cx = s.shape_sphere_cx.data() + p, v.sphere_cy = s.shape_sphere_cy.data() + p;
  v.sphere_cz = s.shape_sphere_cz.data() + p, v.sphere_r = s.shape_sphere_r.data() + p;
  v.num_spheres = L.shape_spheres;
  v.live_spheres = Layout::kSpheresPerAgent * world.num_agents();
  v.spheres_per_body = Layout::kSpheresPerAgent;
  v.body_reach = kAgentReach;
  const size_t c = size_t(env) * L.shape_cylinders;
  v.cyl_cx = s.shape_cyl_cx.data() + c, v.cyl_cy = s.shape_cyl_cy.data() + c;
  v.cyl_r = s.shape_cyl_r.data() + c, v.cyl_h = s.shape_cyl_h.data() + c;
  v.num_cylinders = L.shape_cylinders;
  v.live_cylinders = world.scene().has_target ? 1 : 0;
  return v;
}

}  // namespace hns::batch
