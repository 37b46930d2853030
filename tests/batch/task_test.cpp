// The transfer tasks of docs/game.md §9 on staged scenes: lock-and-return's lock, return and success reward;
// sequential-lock's order (a lock out of order is refused) and its target; shelter's rays, against a hand
// count and the double-precision reference, and its cylinder in lidar and vision; the spoofed observation
// slots that let a hide-and-seek policy act in them; blueprint's smooth-min reward, its completion bonus and
// the absorbed rest of a completed episode, its sites' placement and observations.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "batch/batch_sim.hpp"
#include "batch/scenes.hpp"
#include "physics/geometry.hpp"

namespace hns::batch {
namespace {

using physics::Scene;
using physics::Spawn;

Spawn agent_at(double x, double y) {
  return Spawn{x, y, physics::kAgentRadius, 0.3, 0.3, 0.3};
}
Spawn cube_at(double x, double y) {
  return Spawn{x, y, 0.25, 0.5, 0.5, 0.5};
}

// One lone agent and the given cubes, no walls.
Scene lone_agent_scene(Spawn agent, std::vector<Spawn> boxes) {
  Scene s;
  s.num_hiders = 1;
  s.agents = {agent};
  s.boxes = std::move(boxes);
  return s;
}

BatchConfig task_config(const char* scene) {
  BatchConfig c = scene_config(scene);
  c.num_envs = 1;
  return c;
}

// Agents spawn facing -y: an agent 0.45 m north of a cube's centre (0.2 m from its face) sees it and is in
// lock range.
void stand_north_of(BatchSim& sim, double x, double y) {
  sim.mutable_world(0).set_agent_pose(0, x, y + 0.45, physics::kAgentRadius, 0.0);
  sim.resync(0);
}

AgentAction pressing_lock() {
  AgentAction a;
  a.lock = 1;
  return a;
}

TEST(LockAndReturn, LockThenReturnWithinTenCentimetresOfTheSpawn) {
  BatchSim sim(task_config("lock-and-return"));
  const int A = sim.layout().max_agents;
  ASSERT_EQ(A, 2);  // the lone agent and one spoofed slot
  sim.load_scene(0, lone_agent_scene(agent_at(1.0, 1.0), {cube_at(3.0, 3.0)}));
  const BatchState& s = sim.state();
  EXPECT_EQ(s.task_target[0], 0);
  EXPECT_FLOAT_EQ(s.task_spawn[0], 1.0f);
  EXPECT_FLOAT_EQ(s.task_spawn[1], 1.0f);
  const float to_box = s.task_dist[0];  // from the spawn
  EXPECT_NEAR(to_box, std::hypot(2.0, 2.0), 1e-5);

  // Teleported next to the cube (the shaped term pays the approach), it locks it: +5, and the target is the
  // spawn, 3.2 m away: no success yet.
  stand_north_of(sim, 3.0, 3.0);
  std::vector<AgentAction> act(A, pressing_lock());
  sim.step(act);
  ASSERT_EQ(s.box_locked[0], 1);
  EXPECT_EQ(s.task_target[0], kTargetSpawn);
  const double near_box = std::hypot(2.0, 2.45);
  EXPECT_NEAR(s.task_dist[0], near_box, 0.02);
  EXPECT_NEAR(s.reward[0], 5.0 + 0.5 * to_box, 0.02);
  EXPECT_EQ(s.reward[1], 0.0f);  // the spoofed slot: no agent, no reward

  // 0.15 m from the spawn: closer (shaped) but not returned.
  act.assign(A, AgentAction{});
  sim.mutable_world(0).set_agent_pose(0, 1.15, 1.0, physics::kAgentRadius, 0.0);
  sim.resync(0);
  sim.step(act);
  EXPECT_EQ(s.box_locked[0], 1);  // far from the box, nobody unlocks it
  EXPECT_NEAR(s.reward[0], 0.5 * (near_box - 0.15), 0.02);
  // 0.05 m from it: returned, +1 every step from now on.
  sim.mutable_world(0).set_agent_pose(0, 1.05, 1.0, physics::kAgentRadius, 0.0);
  sim.resync(0);
  sim.step(act);
  EXPECT_NEAR(s.reward[0], 0.5 * 0.10 + 1.0, 0.02);
  sim.step(act);
  EXPECT_NEAR(s.reward[0], 1.0, 0.02);
}

TEST(LockAndReturn, SpoofedSlotsAreEmptyAndMaskedOut) {
  BatchSim sim(task_config("lock-and-return"));
  sim.reset();
  const Layout& L = sim.layout();
  EXPECT_EQ(L.max_agents, 2);
  EXPECT_EQ(L.max_boxes, 1);
  EXPECT_EQ(L.max_ramps, 1);
  const BatchState& s = sim.state();
  EXPECT_EQ(s.agent_exists[1], 0);
  EXPECT_EQ(s.mask_agents[0], 0);
  EXPECT_EQ(s.value_mask_agents[0], 0);
  EXPECT_EQ(s.mask_ramps[0], 0);
  EXPECT_EQ(s.value_mask_ramps[0], 0);
  for (int f = 0; f < Layout::kRampFeatures; ++f) EXPECT_EQ(s.obs_ramps[f], 0.0f);
  EXPECT_EQ(s.obs_self[9], 1.0f);   // a hider
  EXPECT_EQ(s.obs_self[10], 0.0f);  // no preparation phase
  EXPECT_EQ(sim.world(0).scene().layout, physics::Layout::kRandomWalls);
}

TEST(SequentialLock, ALockOutOfOrderIsRefused) {
  BatchSim sim(task_config("sequential-lock"));
  const int A = sim.layout().max_agents;
  // Box 1 is nearer, but box 0 comes first.
  sim.load_scene(0, lone_agent_scene(agent_at(3.6, 1.0), {cube_at(1.0, 3.0), cube_at(3.0, 3.0)}));
  const BatchState& s = sim.state();
  EXPECT_EQ(s.task_target[0], 0);
  const std::vector<AgentAction> lock(A, pressing_lock());

  stand_north_of(sim, 3.0, 3.0);
  for (int k = 0; k < 3; ++k) sim.step(lock);
  EXPECT_EQ(s.box_locked[1], 0) << "box 1 locked before box 0";
  EXPECT_EQ(s.task_target[0], 0);

  stand_north_of(sim, 1.0, 3.0);
  const float before = s.task_dist[0];
  sim.step(lock);
  ASSERT_EQ(s.box_locked[0], 1);
  EXPECT_EQ(s.task_target[0], 1);
  EXPECT_NEAR(s.reward[0], 5.0 + 0.5 * before, 0.02);

  stand_north_of(sim, 3.0, 3.0);
  sim.step(lock);
  EXPECT_EQ(s.box_locked[1], 1) << "box 1 refused after box 0";
  EXPECT_EQ(s.task_target[0], kTargetNone);
  EXPECT_GT(s.reward[0], 5.0 + 1.0 - 0.01);  // the lock and the first success step
}

TEST(SequentialLock, UnlockingAnEarlierBoxSendsTheAgentBackAndCosts) {
  BatchSim sim(task_config("sequential-lock"));
  const int A = sim.layout().max_agents;
  sim.load_scene(0, lone_agent_scene(agent_at(3.6, 1.0), {cube_at(1.0, 3.0), cube_at(3.0, 3.0)}));
  const BatchState& s = sim.state();
  stand_north_of(sim, 1.0, 3.0);
  sim.step(std::vector<AgentAction>(A, pressing_lock()));
  ASSERT_EQ(s.box_locked[0], 1);
  // Standing by it without pressing lock unlocks it (the team rule): -5, and the target is box 0 again.
  sim.step(std::vector<AgentAction>(A, AgentAction{}));
  ASSERT_EQ(s.box_locked[0], 0);
  EXPECT_EQ(s.task_target[0], 0);
  EXPECT_NEAR(s.reward[0], -5.0 - 0.5 * s.task_dist[0], 0.02);
}

// Shelter (docs/game.md §9.3): a cylinder of diameter 1.6 m in the middle of the arena.
Scene shelter_scene(Spawn agent, std::vector<Spawn> boxes, std::vector<physics::StaticBox> walls = {}) {
  Scene s = lone_agent_scene(agent, std::move(boxes));
  s.wall_boxes = std::move(walls);
  s.has_target = true;
  s.target = Spawn{3.0, 3.0, 0.5 * physics::kTargetHeight, 1.6, 1.6, physics::kTargetHeight};
  return s;
}

// The rays the double-precision reference sees reach the cylinder, cast forward from the 100 start points:
// every 5.596 / 25 m around the square [0.202, 5.798]², counter-clockwise from (0.202, 0.202).
int reference_rays_reaching(BatchSim& sim) {
  physics::World& w = sim.mutable_world(0);
  const physics::Occluders occ = w.occluders();
  int reaching = 0;
  const double corner[4][2] = {{0.202, 0.202}, {5.798, 0.202}, {5.798, 5.798}, {0.202, 5.798}};
  for (int side = 0; side < 4; ++side) {
    const double* a = corner[side];
    const double* b = corner[(side + 1) % 4];
    for (int k = 0; k < 25; ++k) {
      const double o[3] = {a[0] + (b[0] - a[0]) * k / 25.0, a[1] + (b[1] - a[1]) * k / 25.0, 0.0};
      double d[3] = {3.0 - o[0], 3.0 - o[1], 0.25};
      const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      for (double& x : d) x /= len;
      reaching += physics::cast_ray(occ, o, d, len, -1).kind == physics::HitKind::kCylinder;
    }
  }
  return reaching;
}

TEST(Shelter, RewardCountsTheRaysThatReachTheCylinder) {
  BatchSim sim(task_config("shelter"));
  const std::vector<AgentAction> idle(sim.layout().max_agents);
  // Nothing in the way but the agent, far out in a corner: all 100 rays arrive.
  sim.load_scene(0, shelter_scene(agent_at(5.75, 3.1), {}));
  sim.step(idle);
  EXPECT_EQ(sim.shelter_rays_reaching(0), reference_rays_reaching(sim));
  EXPECT_GE(sim.shelter_rays_reaching(0), 98);
  EXPECT_NEAR(sim.state().reward[0], -0.001 * sim.shelter_rays_reaching(0), 1e-6);

  // A 0.5 m wall along x = 1.4 (1.35 to 1.45 m) blocks the 25 rays of the left side (y = 5.798 down to
  // 0.426), the 6 of the bottom side that start left of it (x = 0.202 up to 1.321) and the 5 of the top side
  // (x = 1.321 down to 0.426): 64 arrive. The agent stands behind the wall.
  sim.load_scene(
      0, shelter_scene(agent_at(0.8, 3.0), {}, {physics::StaticBox{1.4, 3.0, 0.25, 0.05, 2.8, 0.25}}));
  sim.step(idle);
  EXPECT_EQ(sim.shelter_rays_reaching(0), 64);
  EXPECT_NEAR(sim.state().reward[0], -0.064, 1e-6);
}

TEST(Shelter, AWallOfBoxesBlocksWhatTheReferenceSays) {
  BatchSim sim(task_config("shelter"));
  const std::vector<AgentAction> idle(sim.layout().max_agents);
  // Three y-elongated boxes end to end along x = 1.5 (y from 0.35 to 5.3): gaps at both ends.
  auto slab = [](double y) { return Spawn{1.5, y, 0.25, 0.15, 1.65, 0.5}; };
  sim.load_scene(0, shelter_scene(agent_at(0.8, 3.0), {slab(1.175), slab(2.825), slab(4.475)}));
  sim.step(idle);
  const int reaching = sim.shelter_rays_reaching(0);
  EXPECT_EQ(reaching, reference_rays_reaching(sim));
  EXPECT_GE(reaching, 64);  // the x = 1.5 line cuts at most the left side's 25, the bottom's 6, the top's 5
  EXPECT_LT(reaching, 70);  // the gaps let a few through
  EXPECT_NEAR(sim.state().reward[0], -0.001 * reaching, 1e-6);
}

TEST(Shelter, LidarSeesTheCylinderAndItHidesABox) {
  BatchSim sim(task_config("shelter"));
  // Agent at (3, 5.2) facing -y, the cylinder's near face at y = 3.8, a cube behind it at y = 1.
  sim.load_scene(0, shelter_scene(agent_at(3.0, 5.2), {cube_at(3.0, 1.0)}));
  const BatchState& s = sim.state();
  // Lidar ray k points at 12k degrees from +x: ray 22 (264°) is 6° off -y.
  const double expected = (5.2 - 3.0) / std::cos(6.0 * 3.14159265358979 / 180.0);
  const double hit = s.lidar[22];
  EXPECT_GT(hit, 1.3);
  EXPECT_LT(hit, expected - 0.7);  // meets the cylinder's side 0.8 m out from its axis, not the box
  EXPECT_EQ(s.vis_boxes[0], 0) << "the cube behind the cylinder is seen";
  // Without the cylinder it is seen.
  Scene open = shelter_scene(agent_at(3.0, 5.2), {cube_at(3.0, 1.0)});
  open.has_target = false;
  sim.load_scene(0, open);
  EXPECT_EQ(s.vis_boxes[0], 1);
}

// The paper's agent movement statistic: the largest distance of an agent from its spawn when the episode
// ends.
TEST(EpisodeStatistics, MaxAgentMoveIsTheDistanceFromTheSpawn) {
  BatchConfig c = task_config("lockbox");
  c.world.horizon = 3;
  BatchSim sim(c);
  sim.load_scene(0, lone_agent_scene(agent_at(1.0, 1.0), {cube_at(4.0, 4.0)}));
  sim.mutable_world(0).set_agent_pose(0, 3.0, 1.0, physics::kAgentRadius, 0.0);
  sim.resync(0);
  const std::vector<AgentAction> idle(sim.layout().max_agents);
  for (int t = 0; t < 3; ++t) sim.step(idle);
  ASSERT_EQ(sim.finished().size(), 1u);
  EXPECT_NEAR(sim.finished()[0].max_agent_move, 2.0, 0.02);
}

// Shelter's cylinder over the whole of the original's uniform_placement_middle(0.7) range: its centre reaches
// beyond 3.9 m (the range is 1.4 to 4.25 m) and below 1.7 m, on both axes.
TEST(Shelter, CylinderCentresSpanTheMiddleRange) {
  const physics::WorldConfig w = scene_config("shelter").world;
  double lo = 6, hi = 0;
  for (int seed = 0; seed < 400; ++seed) {
    physics::Rng rng(uint64_t(seed), 0, 0);
    physics::Scene s;
    physics::generate_scene(w.scene, rng, s);
    ASSERT_TRUE(s.has_target);
    for (double v : {s.target.x, s.target.y}) lo = std::min(lo, v), hi = std::max(hi, v);
  }
  EXPECT_GT(hi, 3.9);
  EXPECT_LE(hi, 4.25 + 1e-9);
  EXPECT_LT(lo, 1.7);
  EXPECT_GE(lo, 1.4 - 1e-9);  // c = 9 from cell 3: 0.6 + 1.6 / 2
}

TEST(TransferTasks, PresetsValidateAndPlace) {
  for (const char* name : {"lock-and-return", "sequential-lock", "shelter", "blueprint"}) {
    physics::WorldConfig w = scene_config(name).world;
    EXPECT_NO_THROW(w.validate()) << name;
    EXPECT_NO_THROW(w.scene.check_placeable()) << name;
    const std::string n = name;
    EXPECT_EQ(w.horizon, n == "shelter" ? 240 : n == "blueprint" ? 150 : 120) << name;
    EXPECT_EQ(w.prep_steps(), 0) << name;
  }
  BatchConfig c = task_config("sequential-lock");
  c.num_envs = 4;
  BatchSim sim(c);
  sim.reset();
  for (int e = 0; e < 4; ++e) {
    const Scene& scene = sim.world(e).scene();
    EXPECT_EQ(scene.layout, physics::Layout::kVarTri);
    EXPECT_EQ(scene.boxes.size(), 4u);
    EXPECT_EQ(scene.ramps.size(), 3u);
    EXPECT_EQ(scene.num_hiders + scene.num_seekers, 1);
  }
  c = task_config("shelter");
  c.num_envs = 8;
  BatchSim shelter(c);
  shelter.reset();
  for (int e = 0; e < 8; ++e) {
    const Scene& scene = shelter.world(e).scene();
    ASSERT_TRUE(scene.has_target);
    EXPECT_GE(scene.target.sx, 1.5);
    EXPECT_LE(scene.target.sx, 2.0);
    EXPECT_EQ(scene.boxes.size(), 8u);
    EXPECT_EQ(scene.num_elongated, 3);
    // uniform_placement_middle(0.7) of docs/game.md §2.5: a footprint of c = 8, 9 or 10 cells starts at a
    // cell in [4, 17], [3, 16] or [3, 15]; the cylinder lies within its cells.
    const int c = int(std::ceil(scene.target.sx / physics::kCellSize - 1e-9));
    const int lo = c == 8 ? 4 : 3, hi = c == 8 ? 17 : c == 9 ? 16 : 15;
    EXPECT_GE(scene.target.x - 0.5 * scene.target.sx, lo * physics::kCellSize - 1e-9) << c;
    EXPECT_LE(scene.target.x + 0.5 * scene.target.sx, (hi + c) * physics::kCellSize + 1e-9) << c;
    EXPECT_GE(scene.target.y - 0.5 * scene.target.sx, lo * physics::kCellSize - 1e-9) << c;
    EXPECT_LE(scene.target.y + 0.5 * scene.target.sx, (hi + c) * physics::kCellSize + 1e-9) << c;
    // docs/game.md §9.3's constant observation: the agent's "hider" feature reads 0.
    EXPECT_EQ(shelter.state().obs_self[size_t(e) * shelter.layout().max_agents * Layout::kSelfFeatures + 9],
              0.0f);
    // The boxes spawn anywhere and already block some rays, never all.
    EXPECT_GT(shelter.shelter_rays_reaching(e), 20);
    EXPECT_LT(shelter.shelter_rays_reaching(e), 100);
  }
}

// ---------------------------------------------------------------------------------------------------------
// Blueprint construction (docs/game.md §9.1).

Spawn site_at(double x, double y) {
  return Spawn{x, y, 0.5 * physics::kSiteSize, physics::kSiteSize, physics::kSiteSize, 0.0};
}

Scene blueprint_scene(std::vector<Spawn> sites, std::vector<Spawn> boxes) {
  Scene s = lone_agent_scene(agent_at(0.6, 0.6), std::move(boxes));
  s.sites = std::move(sites);
  return s;
}

// docs/game.md §9.1's smooth minimum of distances, sum d e^(-1.5 d) / sum e^(-1.5 d).
double smooth_min(std::initializer_list<double> d) {
  double num = 0, den = 0;
  for (double x : d) num += x * std::exp(-1.5 * x), den += std::exp(-1.5 * x);
  return num / den;
}

// One site at (3, 3) and one cube 1 m east of it, both axis-aligned: the site's west corners are 1, 1.5,
// sqrt(1.25) and sqrt(2.5) m from the cube's corners, its east corners 0.5, 1, sqrt(0.5) and sqrt(1.25) m.
TEST(Blueprint, DenseRewardIsMinusFivePercentOfTheMeanSmoothMinCornerDistance) {
  BatchSim sim(task_config("blueprint"));
  sim.load_scene(0, blueprint_scene({site_at(3.0, 3.0)}, {cube_at(4.0, 3.0)}));
  std::vector<AgentAction> idle(size_t(sim.layout().max_agents));
  sim.step(idle);
  const double west = smooth_min({1.0, 1.5, std::sqrt(1.25), std::sqrt(2.5)});
  const double east = smooth_min({0.5, 1.0, std::sqrt(0.5), std::sqrt(1.25)});
  EXPECT_NEAR(sim.state().reward[0], -0.05 * (west + east) / 2, 2e-4);
  EXPECT_EQ(sim.state().task_complete[0], 0);
}

// Cubes placed by hand on both sites complete the blueprint: +3 per site on top of the dense reward, and
// the rest of the episode is absorbed (reward 0 whatever happens) until the horizon starts the next one.
// A cube 0.15 m off its site does not count; one 0.05 m off does.
TEST(Blueprint, BoxesPlacedOnTheSitesCompleteItAndTheRestOfTheEpisodeIsAbsorbed) {
  BatchSim sim(task_config("blueprint"));
  const BatchState& s = sim.state();
  std::vector<AgentAction> idle(size_t(sim.layout().max_agents));
  const std::vector<Spawn> sites = {site_at(2.0, 2.0), site_at(4.0, 4.0)};

  sim.load_scene(0, blueprint_scene(sites, {cube_at(2.15, 2.0), cube_at(4.0, 4.0), cube_at(1.0, 5.0)}));
  sim.step(idle);
  EXPECT_EQ(s.task_complete[0], 0) << "0.15 m off: not on its site";
  EXPECT_LT(s.reward[0], 0.0f);

  sim.load_scene(0, blueprint_scene(sites, {cube_at(2.05, 2.0), cube_at(4.0, 4.0), cube_at(1.0, 5.0)}));
  EXPECT_EQ(s.task_complete[0], 0);
  sim.step(idle);
  ASSERT_EQ(s.task_complete[0], 1);
  // The dense term at a (nearly) perfect placement is still the smooth minimum over every box corner: about
  // -0.05 x 0.4.
  EXPECT_GT(s.reward[0], 6.0f - 0.05f);
  EXPECT_LT(s.reward[0], 6.0f - 0.005f);
  EXPECT_EQ(s.reward[1], 0.0f);  // the spoofed slot
  const float completed = s.episode_return[0];

  // Absorbed: even pushing a cube off its site and running out of bounds earn nothing.
  sim.mutable_world(0).set_agent_pose(0, 5.95, 5.95, physics::kAgentRadius, 0.0);
  sim.resync(0);
  std::vector<AgentAction> run = idle;
  run[0].move_x = 10;
  const int horizon = sim.config().world.horizon;
  for (int t = 1; t < horizon; ++t) {
    sim.step(run);
    ASSERT_EQ(s.reward[0], 0.0f) << "step " << t;
    if (t < horizon - 1) {
      ASSERT_EQ(s.task_complete[0], 1);
    }
  }
  EXPECT_EQ(s.done[0], 1);
  ASSERT_EQ(sim.finished().size(), 1u);
  EXPECT_FLOAT_EQ(sim.finished()[0].hider_return, completed);
  EXPECT_EQ(s.task_complete[0], 0) << "the next episode starts open";
}

// Sites: 1 to 4 per episode, each a 3 x 3-cell square of uniform_placement_middle(0.85) (cells 2 to 23:
// centres from 0.65 to 4.95 m), placed before anything movable so no box spawns on one; observed by the lone
// agent as centre and corners, always visible, padding slots zero with mask 0.
TEST(Blueprint, SitesSpanTheMiddleRangeNothingSpawnsOnThemAndTheAgentSeesThem) {
  const physics::WorldConfig w = scene_config("blueprint").world;
  double lo = 6, hi = 0;
  int counts[5] = {};
  for (int seed = 0; seed < 400; ++seed) {
    physics::Rng rng(uint64_t(seed), 0, 0);
    Scene s;
    physics::generate_scene(w.scene, rng, s);
    ASSERT_GE(s.sites.size(), 1u);
    ASSERT_LE(s.sites.size(), 4u);
    ++counts[s.sites.size()];
    EXPECT_EQ(s.boxes.size(), 8u);
    for (const Spawn& c : s.sites) {
      for (double v : {c.x, c.y}) lo = std::min(lo, v), hi = std::max(hi, v);
      for (const Spawn& b : s.boxes)
        EXPECT_GE(std::max(std::fabs(b.x - c.x), std::fabs(b.y - c.y)), 0.5 - 1e-9) << "a box on a site";
    }
  }
  for (int n = 1; n <= 4; ++n) EXPECT_GT(counts[n], 50) << n << " sites";
  EXPECT_GE(lo, 0.65 - 1e-9);
  EXPECT_LT(lo, 0.75);
  EXPECT_LE(hi, 4.95 + 1e-9);
  EXPECT_GT(hi, 4.85);

  BatchConfig c = task_config("blueprint");
  c.num_envs = 6;
  BatchSim sim(c);
  sim.reset();
  const Layout& L = sim.layout();
  ASSERT_EQ(L.max_sites, 4);
  ASSERT_EQ(L.max_agents, 2);
  const BatchState& st = sim.state();
  for (int e = 0; e < c.num_envs; ++e) {
    const Scene& scene = sim.world(e).scene();
    for (int k = 0; k < L.max_sites; ++k) {
      const size_t slot = size_t(e) * L.max_agents * L.max_sites + k;  // agent 0's view of site k
      const float* f = st.obs_sites.data() + slot * Layout::kConstructionSiteFeatures;
      const bool exists = k < int(scene.sites.size());
      EXPECT_EQ(st.mask_sites[slot], exists ? 1 : 0);
      EXPECT_EQ(st.value_mask_sites[slot], exists ? 1 : 0);
      if (!exists) {
        for (int i = 0; i < Layout::kConstructionSiteFeatures; ++i) EXPECT_EQ(f[i], 0.0f);
        continue;
      }
      const Spawn& site = scene.sites[size_t(k)];
      EXPECT_FLOAT_EQ(f[0], float(site.x));
      EXPECT_FLOAT_EQ(f[1], float(site.y));
      EXPECT_FLOAT_EQ(f[2], 0.25f);
      EXPECT_FLOAT_EQ(f[3], float(site.x) - 0.25f);  // corner (-, -)
      EXPECT_FLOAT_EQ(f[4], float(site.y) - 0.25f);
      EXPECT_FLOAT_EQ(f[9], float(site.x) + 0.25f);  // corner (+, +)
      EXPECT_FLOAT_EQ(f[10], float(site.y) + 0.25f);
      EXPECT_EQ(st.mask_sites[slot + L.max_sites], 0) << "the spoofed agent slot sees nothing";
    }
    EXPECT_EQ(st.obs_self[size_t(e) * L.max_agents * Layout::kSelfFeatures + 9],
              0.0f);                                                      // docs/game.md §9: hider 0
    EXPECT_EQ(st.mask_ramps[size_t(e) * L.max_agents * L.max_ramps], 0);  // spoofed ramp slot
  }
}

// ---------------------------------------------------------------------------------------------------------
// Object counting (the paper's §6; docs/transfer.md): the pinned agent sees box k in the gap between the
// screens until it has slid to its side, then never again; its own actions move nothing; no reward.
TEST(ObjectCounting, BoxesSlideToTheirSidesAndVanishBehindTheScreens) {
  BatchConfig c = task_config("object-counting");
  c.num_envs = 4;
  BatchSim sim(c);
  sim.reset();
  const Layout& L = sim.layout();
  ASSERT_EQ(L.max_boxes, 6);
  ASSERT_EQ(L.max_agents, 2);
  const BatchState& s = sim.state();
  std::vector<AgentAction> push(size_t(c.num_envs) * L.max_agents);
  for (AgentAction& a : push) a.move_x = 10, a.move_y = 0, a.turn = 10, a.grab = 1, a.lock = 1;
  const int horizon = c.world.horizon;
  std::vector<int> seen_steps(size_t(c.num_envs) * 6, 0);
  int lefts = 0;
  for (int t = 0; t < horizon; ++t) {
    for (int e = 0; e < c.num_envs; ++e) {
      const size_t ea = size_t(e) * L.max_agents;
      EXPECT_NEAR(s.agent_pos[ea * 3], 3.0f, 1e-4f) << "pinned";
      EXPECT_NEAR(s.agent_pos[ea * 3 + 1], 0.7f, 1e-4f);
      for (int k = 0; k < 6; ++k) seen_steps[size_t(e) * 6 + k] += s.vis_boxes[ea * L.max_boxes + k];
      // Box k is seen only while it is near the gap's column; after step 57 every box is hidden.
      if (t >= 57) {
        for (int k = 0; k < 6; ++k) {
          ASSERT_EQ(s.vis_boxes[ea * L.max_boxes + k], 0) << "t " << t << " box " << k;
        }
      }
      if (t == horizon - 1) {
        const physics::Scene& scene = sim.world(e).scene();
        ASSERT_EQ(scene.sides.size(), 6u);
        for (int k = 0; k < 6; ++k) {
          EXPECT_NEAR(s.box_pos[(size_t(e) * L.max_boxes + k) * 3], 3.0 + 2.4 * scene.sides[size_t(k)], 1e-4);
          lefts += scene.sides[size_t(k)] < 0;
        }
      }
    }
    if (t == 0) {
      EXPECT_EQ(s.vis_boxes[0], 1) << "the first box stands in the gap";
    }
    sim.step(push);
    for (int e = 0; e < c.num_envs; ++e) EXPECT_EQ(s.reward[size_t(e) * L.max_agents], 0.0f);
  }
  for (int v : seen_steps) EXPECT_GT(v, 0) << "every box is seen at some step";
  EXPECT_GT(lefts, 0);
  EXPECT_LT(lefts, 24);
}

}  // namespace
}  // namespace hns::batch
