// The rules of the games (docs/game.md §5, §9): rewards and dones after each step, the box-locking tasks'
// targets, shelter's rays, blueprint's construction sites, object counting's script and the food variants'
// eating, with the observation rows of the sites and the food.
#include <algorithm>
#include <cmath>
#include <limits>

#include "batch/env.hpp"

namespace hns::batch {
namespace {

constexpr float kOutOfBoundsReward = -10.0f;  // docs/game.md §5.2

// The target of agent 0 (docs/game.md §9.2): the nearest unlocked box, or in kSequentialLock the first
// unlocked one in index order; once every box is locked, the spawn point in kLockReturn (kTargetSpawn) and
// none otherwise (kTargetNone). task_dist: the 2-D distance to it.
void lockbox_retarget(EnvRef& ref) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const bool in_order = ref.config.world.lock_in_order();
  const float* agent = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
  int best = kTargetNone;
  float best_d = 0.0f;
  for (int b = 0; b < L.max_boxes; ++b) {
    const size_t i = size_t(env) * L.max_boxes + b;
    if (s.box_exists[i] == 0 || s.box_locked[i] != 0) continue;
    const float d = std::hypot(s.box_pos[3 * i] - agent[0], s.box_pos[3 * i + 1] - agent[1]);
    if (best < 0 || d < best_d) best = b, best_d = d;
    if (in_order) break;
  }
  if (best == kTargetNone && ref.config.world.task == physics::WorldConfig::Task::kLockReturn) {
    const float* spawn = s.task_spawn.data() + size_t(env) * 2;
    best = kTargetSpawn;
    best_d = std::hypot(spawn[0] - agent[0], spawn[1] - agent[1]);
  }
  s.task_target[env] = best;
  s.task_dist[env] = best_d;
}

// docs/game.md §9.2 for agent 0 (every agent of the env gets the same reward): +lock_reward per newly locked
// box, -unlock_penalty per newly unlocked one; shaped_reward_scale x the decrease of the 2-D distance to the
// target, +scale x the old distance when the target box gets locked, -scale x the new target's distance when
// a box gets unlocked; +success_reward every step the task is complete: all boxes locked (and in kLockReturn
// agent 0 within return_threshold of its spawn).
void lockbox_rewards(EnvRef& ref, float* reward) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const physics::WorldConfig& wc = ref.config.world;
  const uint8_t* locked = s.box_locked.data() + size_t(env) * L.max_boxes;
  uint8_t* before = s.task_locked.data() + size_t(env) * L.max_boxes;
  int newly_locked = 0, newly_unlocked = 0;
  for (int b = 0; b < L.max_boxes; ++b) {
    newly_locked += locked[b] != 0 && before[b] == 0;
    newly_unlocked += locked[b] == 0 && before[b] != 0;
    before[b] = locked[b];
  }
  double r = wc.lock_reward * newly_locked - wc.unlock_penalty * newly_unlocked;
  const int target = s.task_target[env];
  const double old_dist = s.task_dist[env];
  if (target >= 0 && locked[target] != 0) {
    r += wc.shaped_reward_scale * old_dist;
    lockbox_retarget(ref);
  } else if (newly_unlocked > 0) {
    lockbox_retarget(ref);
    r -= wc.shaped_reward_scale * s.task_dist[env];
  } else if (target != kTargetNone) {
    lockbox_retarget(ref);
    r += wc.shaped_reward_scale * (old_dist - s.task_dist[env]);
  }
  const int now = s.task_target[env];
  if (now == kTargetNone || (now == kTargetSpawn && s.task_dist[env] <= wc.return_threshold)) {
    r += wc.success_reward;
  }
  std::fill_n(reward, L.max_agents, float(r));
}

// The shelter reward's rays (docs/game.md §9.3): 100 start points evenly spaced around the square
// [0.202, 5.798]² on the floor, 25 per side, each side's from its first corner (counter-clockwise from
// (0.202, 0.202)) up to but not including the next, aimed at the cylinder's centre. A ray reaches the
// cylinder when nothing else lies on the segment from its start to the cylinder; the segments are cast the
// other way, as one fan from the centre that skips the cylinder (nothing else can be inside it), so the 100
// rays share the vector kernel's blocks.
constexpr int kShelterRaysPerSide = 25;
constexpr int kShelterRays = 4 * kShelterRaysPerSide;
constexpr float kShelterEdgeLo = 0.202f, kShelterEdgeHi = 5.798f;  // m
constexpr float kShelterRayCost = 0.001f;                          // reward per ray that reaches the cylinder

// Blueprint construction (docs/game.md §9.1). Box corners are the middles of a box's vertical edges, (±sx/2,
// ±sy/2, 0) from its centre turned by its yaw (tilt is ignored: the batch mirrors yaw only); a site's corners
// are (±0.25, ±0.25, 0) from its centre. Dense: for each site corner, the smooth minimum over every box
// corner of the distance, sum d e^(αd) / sum e^(αd) with α = -1.5; the reward is -0.05 x their mean.
// Completion: every site has a box centre within 0.1 m of its centre and every site corner a box corner
// within 0.1 m; it pays 3 per site (on top of that step's dense reward) and sets task_complete.
constexpr double kBlueprintAlpha = -1.5;
constexpr double kBlueprintDenseScale = 0.05;
constexpr double kBlueprintRadius = 0.1;      // m
constexpr double kBlueprintSiteReward = 3.0;  // per site, on completion

void blueprint_rewards(EnvRef& ref, float* reward) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const int nb = ref.world.num_boxes();
  const size_t eb = size_t(env) * L.max_boxes, ec = size_t(env) * L.construction_sites;
  constexpr double kSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
  auto box_corner = [&](int b, int k, double* out) {
    const float* p = s.box_pos.data() + (eb + b) * 3;
    const float* r = s.box_rot.data() + (eb + b) * 2;
    const float* sz = s.box_size.data() + (eb + b) * 3;
    const double lx = kSigns[k][0] * 0.5 * sz[0], ly = kSigns[k][1] * 0.5 * sz[1];
    out[0] = p[0] + r[0] * lx - r[1] * ly;
    out[1] = p[1] + r[1] * lx + r[0] * ly;
    out[2] = p[2];
  };
  auto dist = [](const double* a, const double* b) {
    return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                     (a[2] - b[2]) * (a[2] - b[2]));
  };
  double smooth_sum = 0.0;
  int site_corners = 0, sites = 0;
  bool complete = nb > 0;
  for (int c = 0; c < L.construction_sites; ++c) {
    if (s.site_exists[ec + c] == 0) continue;
    ++sites;
    const float* sp = s.site_pos.data() + (ec + c) * 3;
    const double centre[3] = {sp[0], sp[1], sp[2]};
    double nearest_centre = std::numeric_limits<double>::infinity();
    for (int b = 0; b < nb; ++b) {
      const float* p = s.box_pos.data() + (eb + b) * 3;
      const double box[3] = {p[0], p[1], p[2]};
      nearest_centre = std::min(nearest_centre, dist(centre, box));
    }
    complete = complete && nearest_centre < kBlueprintRadius;
    for (int k = 0; k < 4; ++k) {
      const double corner[3] = {centre[0] + kSigns[k][0] * 0.5 * physics::kSiteSize,
                                centre[1] + kSigns[k][1] * 0.5 * physics::kSiteSize, centre[2]};
      double num = 0.0, den = 0.0, nearest = std::numeric_limits<double>::infinity();
      for (int b = 0; b < nb; ++b) {
        for (int q = 0; q < 4; ++q) {
          double bc[3];
          box_corner(b, q, bc);
          const double d = dist(corner, bc), w = std::exp(kBlueprintAlpha * d);
          num += d * w;
          den += w;
          nearest = std::min(nearest, d);
        }
      }
      smooth_sum += den > 0.0 ? num / den : 0.0;
      ++site_corners;
      complete = complete && nearest < kBlueprintRadius;
    }
  }
  double r = site_corners > 0 ? -kBlueprintDenseScale * smooth_sum / site_corners : 0.0;
  if (complete && sites > 0) {
    r += kBlueprintSiteReward * sites;
    s.task_complete[env] = 1;
  }
  std::fill_n(reward, L.max_agents, float(r));
}

// Object counting: the agent pinned at its spot facing +y (yaw pi: an agent faces (sin yaw, -cos yaw)), box k
// where the script has it after this many steps (docs/transfer.md "Object counting").
void pose_counting(EnvRef& ref) {
  physics::World& world = ref.world;
  const physics::Scene& scene = world.scene();
  const int t = world.step_count();
  // Only what is off its place is moved: a body left alone can go to sleep (ODE's auto-disable), which makes
  // the scene's step about three times cheaper than posing every body every step.
  constexpr double kTolerance = 1e-5;  // m
  auto off = [](const physics::BodyState& st, double x, double y) {
    return std::abs(st.pos[0] - x) > kTolerance || std::abs(st.pos[1] - y) > kTolerance;
  };
  const physics::BodyState agent = world.agent_state(0);
  if (t == 0 || off(agent, physics::kCountingAgentX, physics::kCountingAgentY) || agent.cos_yaw > -1 + 1e-6) {
    world.set_agent_pose(0, physics::kCountingAgentX, physics::kCountingAgentY, physics::kAgentRadius,
                         3.14159265358979323846);
  }
  for (int k = 0; k < world.num_boxes(); ++k) {
    const int side =
        k < int(scene.sides.size()) ? scene.sides[size_t(k)] : 1;  // a staged scene may omit them
    const double x = physics::counting_box_x(k, t, side),
                 y = physics::kCountingRow0 + k * physics::kCountingRowStep;
    if (t == 0 || off(world.box_state(k), x, y)) world.set_box_pose(k, x, y, 0.5 * physics::kBoxSize, 0.0);
  }
}

// The food variants (docs/game.md §5.4), after the step: every hider the previous observation let eat an item
// (food_eat_ok) and within eat_radius of it eats 1 unit of it, outside the preparation phase; hiders that
// would together eat more than is left share it. An item eaten up stays at 0 for respawn_steps steps (the
// step it was emptied counts as the first), then its health resets, at a new spot with relocate. Each hider
// gets the units it ate, or the hiders' mean of them (joint_mean), times reward_scale; seekers get nothing.
void food_after_step(EnvRef& ref, float* reward, bool prep) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const physics::FoodConfig& fc = ref.config.world.food;
  const int n = ref.world.num_agents(), F = L.max_food;
  const size_t ea = size_t(env) * L.max_agents, ef = size_t(env) * F;
  const float* pos = s.agent_pos.data() + ea * 3;
  const uint8_t* hider = s.agent_hider.data() + ea;
  const uint8_t* eat_ok = s.food_eat_ok.data() + ea * F;
  float* eaten = s.food_eaten.data() + ea;
  std::fill_n(eaten, L.max_agents, 0.0f);
  const float reach2 = float(fc.eat_radius * fc.eat_radius);
  float total = 0.0f;
  for (int f = 0; f < F; ++f) {
    const size_t i = ef + size_t(f);
    if (s.food_exists[i] == 0) continue;
    float* p = s.food_pos.data() + i * 3;
    float& health = s.food_health[i];
    auto eats = [&](int a) {
      if (prep || health <= 0.0f || eat_ok[a * F + f] == 0) return false;
      const float dx = pos[3 * a] - p[0], dy = pos[3 * a + 1] - p[1], dz = pos[3 * a + 2] - p[2];
      return dx * dx + dy * dy + dz * dz < reach2;
    };
    int count = 0;
    for (int a = 0; a < n; ++a) count += eats(a) ? 1 : 0;
    if (count > 0) {
      const float share = std::min(1.0f, health / float(count));
      for (int a = 0; a < n; ++a)
        if (eats(a)) eaten[a] += share;
      health = std::max(0.0f, health - share * float(count));
      total += share * float(count);
    }
    int32_t& empty_steps = s.food_respawn[i];
    if (fc.respawn_steps > 0 && empty_steps == fc.respawn_steps) {
      health = float(fc.max_health);
      if (fc.relocate) {
        const auto [x, y] = physics::food_respawn_spot(ref.config.world.scene, ref.rng);
        p[0] = float(x), p[1] = float(y);
        // This step's vision looked at the old spot: the moved item counts as unseen until the next step's
        // vision (masked in this observation, not eaten at the next step).
        for (int a = 0; a < L.max_agents; ++a) s.vis_food[(size_t(env) * L.max_agents + a) * F + f] = 0;
      }
    }
    empty_steps = health <= 0.0f ? empty_steps + 1 : 0;
  }
  s.stat_run[size_t(env) * Layout::kRunStats + kFoodEaten] += total;
  float hider_units = 0.0f;
  int hiders = 0;
  for (int a = 0; a < n; ++a) {
    hider_units += hider[a] != 0 ? eaten[a] : 0.0f;
    hiders += hider[a];
  }
  const float scale = float(fc.reward_scale);
  for (int a = 0; a < n; ++a) {
    if (hider[a] == 0) continue;
    reward[a] += scale * (fc.joint_mean ? hider_units / float(hiders) : eaten[a]);
  }
}

}  // namespace

int shelter_rays_reaching(const Layout& L, const BatchState& s, const physics::World& world, int env) {
  const physics::Scene& scene = world.scene();
  if (!scene.has_target) return 0;
  const ShapesView shapes = shapes_view(L, s, world, env);
  const float cx = float(scene.target.x), cy = float(scene.target.y), cz = float(scene.target.z);
  alignas(64) float dx[kShelterRays], dy[kShelterRays], dz[kShelterRays], len[kShelterRays], t[kShelterRays];
  alignas(64) int32_t id[kShelterRays];
  for (int side = 0; side < 4; ++side) {
    for (int k = 0; k < kShelterRaysPerSide; ++k) {
      const int i = side * kShelterRaysPerSide + k;
      const float step = (kShelterEdgeHi - kShelterEdgeLo) * float(k) / kShelterRaysPerSide;
      const float up = kShelterEdgeLo + step, down = kShelterEdgeHi - step;
      const float ox = side == 0 ? up : side == 1 ? kShelterEdgeHi : side == 2 ? down : kShelterEdgeLo;
      const float oy = side == 0 ? kShelterEdgeLo : side == 1 ? up : side == 2 ? kShelterEdgeHi : down;
      const float ex = ox - cx, ey = oy - cy, ez = 0.0f - cz;
      len[i] = std::sqrt(ex * ex + ey * ey + ez * ez);
      dx[i] = ex / len[i], dy[i] = ey / len[i], dz[i] = ez / len[i];
    }
  }
  first_hits(shapes, RayFan{cx, cy, cz, dx, dy, dz, len, kShelterRays, shapes.cylinder_id(0)}, t, id);
  int reaching = 0;
  for (int i = 0; i < kShelterRays; ++i) reaching += id[i] < 0;
  return reaching;
}

void rewards(EnvRef& ref) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const physics::WorldConfig& wc = ref.config.world;
  const physics::World& world = ref.world;
  const int t = world.step_count();
  s.step_count[env] = t;
  const int n = world.num_agents();
  const float* pos = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
  const uint8_t* hider = s.agent_hider.data() + size_t(env) * L.max_agents;
  const uint8_t* vis = s.vis_agents.data() + size_t(env) * L.max_agents * L.max_agents;
  const double* rect = wc.restrict_rect;
  auto outside = [rect](const float* p) {
    return p[0] < rect[0] || p[0] > rect[2] || p[1] < rect[1] || p[1] > rect[3];
  };

  // Joint zero-sum (docs/game.md §5.1): every hider gets -1 if any hider is seen by any seeker, else +1;
  // seekers the opposite. Out of bounds replaces an agent's reward with -10; in the quadrant game any box or
  // ramp out of bounds costs everyone -10 (§5.2). Everything is 0 during the preparation phase.
  bool any_seen = false;
  for (int sk = 0; sk < n; ++sk) {
    if (hider[sk] != 0) continue;
    for (int h = 0; h < n; ++h) any_seen = any_seen || (hider[h] != 0 && vis[sk * L.max_agents + h] != 0);
  }
  bool objects_out = false;
  if (wc.penalize_objects_out) {
    for (int b = 0; b < world.num_boxes(); ++b)
      objects_out = objects_out || outside(s.box_pos.data() + ((size_t(env) * L.max_boxes + b) * 3));
    for (int r = 0; r < world.num_ramps(); ++r)
      objects_out = objects_out || outside(s.ramp_pos.data() + ((size_t(env) * L.max_ramps + r) * 3));
  }
  const bool prep = t <= wc.prep_steps();
  float* reward = s.reward.data() + size_t(env) * L.max_agents;
  if (wc.is_transfer_task()) {
    // A completed blueprint absorbs the rest of its episode: reward 0, whatever happens (the trainer leaves
    // those steps out).
    const bool absorbed = s.task_complete[env] != 0;
    if (absorbed) {
      std::fill_n(reward, L.max_agents, 0.0f);
    } else if (wc.is_lock_task()) {
      lockbox_rewards(ref, reward);
    } else if (wc.task == physics::WorldConfig::Task::kBlueprint) {
      blueprint_rewards(ref, reward);
    } else if (wc.task == physics::WorldConfig::Task::kCounting) {
      std::fill_n(reward, L.max_agents, 0.0f);  // a supervised probe: no reward
    } else {
      std::fill_n(reward, L.max_agents, -kShelterRayCost * float(shelter_rays_reaching(L, s, world, env)));
    }
    for (int a = 0; a < L.max_agents; ++a) {
      if (!absorbed && a < n && outside(pos + 3 * a)) reward[a] = kOutOfBoundsReward;
      if (a >= n) reward[a] = 0.0f;
    }
    s.episode_return[size_t(env) * 2] += reward[0];
    s.done[env] = world.done() ? 1 : 0;
    return;
  }
  for (int a = 0; a < L.max_agents; ++a) {
    float r = 0.0f;
    if (a < n && !prep) {
      r = (hider[a] != 0) == any_seen ? -1.0f : 1.0f;
      if (objects_out || outside(pos + 3 * a)) r = kOutOfBoundsReward;
    }
    reward[a] = r;
  }
  if (L.max_food > 0) food_after_step(ref, reward, prep);  // added to the game's (its wrapper is outermost)
  float hider_sum = 0, seeker_sum = 0;
  int hiders = 0;
  for (int a = 0; a < n; ++a) {
    (hider[a] != 0 ? hider_sum : seeker_sum) += reward[a];
    hiders += hider[a];
  }
  float* ret = s.episode_return.data() + size_t(env) * 2;
  if (hiders > 0) ret[0] += hider_sum / hiders;
  if (n - hiders > 0) ret[1] += seeker_sum / (n - hiders);
  if (!prep) track_seeking(ref, any_seen);

  // Statistics at the end of the preparation phase (docs/game.md §7): when prep_obs first reads 1, after step
  // prep_steps + 1 (or at the last step of an episode too short for that).
  if (t == std::min(wc.prep_steps() + 1, wc.horizon)) {
    measure_stats(ref, s.stat_prep.data() + size_t(env) * Layout::kPrepStats);
  }
  s.done[env] = world.done() ? 1 : 0;
}

void start_rules(EnvRef& ref, uint64_t episode) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const physics::Scene& scene = ref.world.scene();
  const int nc = int(scene.sites.size()), nf = int(scene.food.size());
  for (int c = 0; c < L.construction_sites; ++c) {
    float* p = s.site_pos.data() + (size_t(env) * L.construction_sites + c) * 3;
    p[0] = c < nc ? float(scene.sites[c].x) : 0.0f;
    p[1] = c < nc ? float(scene.sites[c].y) : 0.0f;
    p[2] = c < nc ? float(scene.sites[c].z) : 0.0f;
    s.site_exists[size_t(env) * L.construction_sites + c] = c < nc ? 1 : 0;
  }
  for (int f = 0; f < L.max_food; ++f) {
    const size_t i = size_t(env) * L.max_food + f;
    float* p = s.food_pos.data() + i * 3;
    p[0] = f < nf ? float(scene.food[f].x) : 0.0f;
    p[1] = f < nf ? float(scene.food[f].y) : 0.0f;
    p[2] = f < nf ? float(scene.food[f].z) : 0.0f;
    s.food_health[i] = f < nf ? float(ref.config.world.food.max_health) : 0.0f;
    s.food_respawn[i] = 0;
    s.food_exists[i] = f < nf ? 1 : 0;
  }
  std::fill_n(s.food_eaten.data() + size_t(env) * L.max_agents, L.max_agents, 0.0f);
  ref.rng =
      physics::Rng(ref.config.seed ^ 0xF00DF00DULL, uint64_t(ref.config.first_env) + uint64_t(env), episode);
  if (ref.config.world.task == physics::WorldConfig::Task::kCounting) pose_counting(ref);
}

void rules_started(EnvRef& ref) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  std::copy_n(s.box_locked.data() + size_t(env) * L.max_boxes, L.max_boxes,
              s.task_locked.data() + size_t(env) * L.max_boxes);
  if (ref.config.world.is_lock_task()) {
    const float* agent = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
    s.task_spawn[size_t(env) * 2] = agent[0];
    s.task_spawn[size_t(env) * 2 + 1] = agent[1];
    lockbox_retarget(ref);
  }
}

bool scripted(const EnvRef& ref) {
  return ref.config.world.task == physics::WorldConfig::Task::kCounting;
}

void after_physics(EnvRef& ref) {
  if (scripted(ref)) pose_counting(ref);
}

// Construction sites (docs/game.md §9.1): centre, then the corners (-,-), (+,-), (+,+), (-,+); always
// visible.
void observe_sites(EnvRef& ref) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const int A = L.max_agents, C = L.max_sites, CS = L.construction_sites, SF = L.site_features;
  const size_t ea = size_t(env) * A;
  float* obs_sites = s.obs_sites.data() + ea * C * SF;
  uint8_t* mask_sites = s.mask_sites.data() + ea * C;
  uint8_t* value_mask_sites = s.value_mask_sites.data() + ea * C;
  for (int a = 0; a < ref.world.num_agents(); ++a) {
    for (int c = 0; c < CS; ++c) {
      const size_t i = size_t(env) * CS + c;
      if (s.site_exists[i] == 0) continue;
      float* out = obs_sites + (size_t(a) * C + c) * SF;
      const float* p = s.site_pos.data() + 3 * i;
      std::copy_n(p, 3, out);
      constexpr float kHalf = float(0.5 * physics::kSiteSize);
      constexpr float kSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
      for (int k = 0; k < 4; ++k) {
        out[3 + 3 * k] = p[0] + kSigns[k][0] * kHalf;
        out[4 + 3 * k] = p[1] + kSigns[k][1] * kHalf;
        out[5 + 3 * k] = p[2];
      }
      mask_sites[a * C + c] = 1;
      value_mask_sites[a * C + c] = 1;
    }
  }
}

// Food (docs/game.md §5.4): position and health, seen through vision; a hider may eat what it sees while no
// hider is seen (unless eat_when_caught), which the next step's eating reads.
void observe_food(EnvRef& ref) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const int A = L.max_agents, C = L.max_sites, F = L.max_food, SF = L.site_features;
  const int n = ref.world.num_agents();
  const size_t ea = size_t(env) * A;
  float* obs_sites = s.obs_sites.data() + ea * C * SF;
  uint8_t* mask_sites = s.mask_sites.data() + ea * C;
  uint8_t* value_mask_sites = s.value_mask_sites.data() + ea * C;
  uint8_t* eat_ok = s.food_eat_ok.data() + ea * F;
  const uint8_t* hider = s.agent_hider.data() + ea;
  const uint8_t* vis_agents = s.vis_agents.data() + ea * A;
  const uint8_t* vis_food = s.vis_food.data() + ea * F;
  // No hider is seen by a seeker in this observation (the food variants' eating mask).
  bool eat_free = true;
  for (int sk = 0; sk < n && F > 0; ++sk) {
    if (hider[sk] != 0) continue;
    for (int h = 0; h < n; ++h) eat_free = eat_free && !(hider[h] != 0 && vis_agents[sk * A + h] != 0);
  }
  for (int a = 0; a < n; ++a) {
    for (int f = 0; f < F; ++f) {
      const size_t i = size_t(env) * F + f;
      if (s.food_exists[i] == 0) continue;
      float* out = obs_sites + (size_t(a) * C + f) * SF;
      std::copy_n(s.food_pos.data() + 3 * i, 3, out);
      out[3] = s.food_health[i];
      const uint8_t seen = vis_food[a * F + f];
      mask_sites[a * C + f] = seen;
      value_mask_sites[a * C + f] = 1;
      eat_ok[a * F + f] =
          hider[a] != 0 && seen != 0 && (eat_free || ref.config.world.food.eat_when_caught) ? 1 : 0;
    }
  }
}

}  // namespace hns::batch
