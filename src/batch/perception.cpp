// Perception: what each agent sees (docs/game.md §4.1: a view cone and lines of sight, also the world's
// object visibility that grab and lock use in the next step) and its lidar (§4.2), both cast by the vector
// ray kernel (ray_kernels.hpp) against the shapes the mirror placed.
#include <algorithm>
#include <cmath>

#include "batch/env.hpp"

namespace hns::batch {
namespace {

// The lidar fan (docs/game.md §4.2, §14.6): world-fixed horizontal directions 12° apart from +x, each 6 m
// long.
struct LidarFan {
  float dx[Layout::kLidar], dy[Layout::kLidar], dz[Layout::kLidar], length[Layout::kLidar];
  LidarFan() {
    for (int k = 0; k < Layout::kLidar; ++k) {
      const double angle = 2.0 * 3.14159265358979323846 * k / Layout::kLidar;
      dx[k] = float(std::cos(angle));
      dy[k] = float(std::sin(angle));
      dz[k] = 0.0f;
      length[k] = float(physics::kLidarRange);
    }
  }
};
const LidarFan kLidarFan;
const float kCosHalfCone = float(std::cos(physics::kVisionHalfAngle));

// Cone test (docs/game.md §4.1): the target lies within 67.5° of the viewer's facing direction (−y at yaw 0).
bool in_cone(const float* viewer_pos, const float* viewer_rot, const float* target_pos) {
  const float dx = target_pos[0] - viewer_pos[0], dy = target_pos[1] - viewer_pos[1];
  const float fx = viewer_rot[1], fy = -viewer_rot[0];
  const float len = std::sqrt(dx * dx + dy * dy);
  return len == 0.0f || dx * fx + dy * fy >= kCosHalfCone * len;
}

}  // namespace

// Vision (docs/game.md §4.1): a target is seen when its sight point lies in the viewer's cone and the first
// shape on the segment from the viewer's centre to that point is the target itself (an agent's arms count as
// the agent). Sight points are centres, a ramp's its centroid (physics::ramp_sight_point): all lie inside
// their solid, so the segment always enters the target well before its end. Each viewer's lines of sight to
// the targets in its cone form one ray fan.
void vision(EnvRef& ref) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const ShapesView shapes = shapes_view(ref);
  const int walls = s.num_walls[env];
  const float* agent_pos = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
  const float* agent_rot = s.agent_rot.data() + size_t(env) * L.max_agents * 2;
  const uint8_t* agent_exists = s.agent_exists.data() + size_t(env) * L.max_agents;
  const float* box_pos = s.box_pos.data() + size_t(env) * L.max_boxes * 3;
  const uint8_t* box_exists = s.box_exists.data() + size_t(env) * L.max_boxes;
  const float* ramp_pos = s.ramp_pos.data() + size_t(env) * L.max_ramps * 3;
  const float* ramp_rot = s.ramp_rot.data() + size_t(env) * L.max_ramps * 2;
  const uint8_t* ramp_exists = s.ramp_exists.data() + size_t(env) * L.max_ramps;
  uint8_t* vis_agents = s.vis_agents.data() + size_t(env) * L.max_agents * L.max_agents;
  uint8_t* vis_boxes = s.vis_boxes.data() + size_t(env) * L.max_agents * L.max_boxes;
  uint8_t* vis_ramps = s.vis_ramps.data() + size_t(env) * L.max_agents * L.max_ramps;
  const float* food_pos = s.food_pos.data() + size_t(env) * L.max_food * 3;
  const uint8_t* food_exists = s.food_exists.data() + size_t(env) * L.max_food;
  uint8_t* vis_food = s.vis_food.data() + size_t(env) * L.max_agents * L.max_food;
  std::fill_n(vis_agents, L.max_agents * L.max_agents, 0);
  std::fill_n(vis_boxes, L.max_agents * L.max_boxes, 0);
  std::fill_n(vis_ramps, L.max_agents * L.max_ramps, 0);
  std::fill_n(vis_food, L.max_agents * L.max_food, 0);

  // One viewer's lines of sight: unit direction and length per target in the cone, the shape id that must
  // be hit first, and the visibility flag to set.
  float dx[kMaxSightLines], dy[kMaxSightLines], dz[kMaxSightLines], len[kMaxSightLines], t[kMaxSightLines];
  int32_t want[kMaxSightLines], hit[kMaxSightLines];
  uint8_t* flag[kMaxSightLines];
  for (int a = 0; a < L.max_agents; ++a) {
    if (agent_exists[a] == 0) continue;
    const float* o = agent_pos + 3 * a;
    int n = 0;
    auto aim = [&](const float* target, int target_id, uint8_t* out) {
      if (!in_cone(o, agent_rot + 2 * a, target)) return;
      const float ex = target[0] - o[0], ey = target[1] - o[1], ez = target[2] - o[2];
      const float d = std::sqrt(ex * ex + ey * ey + ez * ez);
      if (d < 1e-6f) {
        *out = 1;  // the same centre: nothing can be in between
        return;
      }
      dx[n] = ex / d, dy[n] = ey / d, dz[n] = ez / d, len[n] = d;
      want[n] = target_id, flag[n] = out;
      ++n;
    };
    vis_agents[a * L.max_agents + a] = 1;
    for (int j = 0; j < L.max_agents; ++j) {
      if (j != a && agent_exists[j] != 0)
        aim(agent_pos + 3 * j, shapes.sphere_id(j), &vis_agents[a * L.max_agents + j]);
    }
    for (int b = 0; b < L.max_boxes; ++b) {
      if (box_exists[b] != 0) aim(box_pos + 3 * b, walls + b, &vis_boxes[a * L.max_boxes + b]);
    }
    for (int r = 0; r < L.max_ramps; ++r) {
      if (ramp_exists[r] == 0) continue;
      const float* p = ramp_pos + 3 * r;
      float centroid[3];
      physics::ramp_sight_point(p[0], p[1], p[2], ramp_rot[2 * r], ramp_rot[2 * r + 1], centroid);
      aim(centroid, shapes.wedge_id(r), &vis_ramps[a * L.max_ramps + r]);
    }
    // A food item is a point, not a shape: seen when nothing lies on the segment to it (docs/game.md §4.1's
    // rule for site targets), so the shape that must be hit first is none (-1).
    for (int f = 0; f < L.max_food; ++f) {
      if (food_exists[f] != 0) aim(food_pos + 3 * f, -1, &vis_food[a * L.max_food + f]);
    }
    first_hits(shapes, RayFan{o[0], o[1], o[2], dx, dy, dz, len, n, shapes.sphere_id(a)}, t, hit);
    for (int k = 0; k < n; ++k) *flag[k] = hit[k] == want[k] ? 1 : 0;
  }
  // The world's grab and lock use this step's object visibility in the next step.
  physics::World& world = ref.world;
  std::span<uint8_t> object_vis = world.object_visibility();
  const int n_obj = world.num_objects();
  for (int a = 0; a < world.num_agents(); ++a) {
    for (int b = 0; b < world.num_boxes(); ++b) object_vis[a * n_obj + b] = vis_boxes[a * L.max_boxes + b];
    for (int r = 0; r < world.num_ramps(); ++r) {
      object_vis[a * n_obj + world.num_boxes() + r] = vis_ramps[a * L.max_ramps + r];
    }
  }
}

// Lidar (docs/game.md §4.2, §14.6): per agent one fan of 30 world-fixed horizontal rays, the first hit within
// 6 m, else 6. Empty agent slots read 0.
void lidar(EnvRef& ref) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const ShapesView shapes = shapes_view(ref);
  const float* agent_pos = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
  const uint8_t* agent_exists = s.agent_exists.data() + size_t(env) * L.max_agents;
  float* lidar = s.lidar.data() + size_t(env) * L.max_agents * Layout::kLidar;
  int32_t hit[Layout::kLidar];
  for (int a = 0; a < L.max_agents; ++a) {
    float* out = lidar + a * Layout::kLidar;
    if (agent_exists[a] == 0) {
      std::fill_n(out, Layout::kLidar, 0.0f);
      continue;
    }
    const float* o = agent_pos + 3 * a;
    first_hits(shapes,
               RayFan{o[0], o[1], o[2], kLidarFan.dx, kLidarFan.dy, kLidarFan.dz, kLidarFan.length,
                      Layout::kLidar, shapes.sphere_id(a)},
               out, hit);
    for (int k = 0; k < Layout::kLidar; ++k) {
      if (hit[k] < 0) out[k] = float(physics::kLidarRange);
    }
  }
}

}  // namespace hns::batch
