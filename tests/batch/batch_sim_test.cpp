// BatchSim: vision and lidar on hand-built scenes, rewards, auto-reset, observation layout, determinism.
#include "batch/batch_sim.hpp"
#include "batch/scenes.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <string>
#include <vector>

namespace hns::batch {
namespace {

using physics::Scene;
using physics::Spawn;

constexpr double kPi = 3.14159265358979323846;

// A batch with room for 2 hiders, 2 seekers, 4 boxes and 2 ramps; no preparation phase.
BatchConfig test_config(int envs = 1) {
  BatchConfig c;
  c.world = physics::WorldConfig::empty();
  c.world.scene.hiders = {1, 2};
  c.world.scene.seekers = {1, 2};
  c.world.scene.boxes = {0, 4};
  c.world.scene.elongated = {0, 4};
  c.world.scene.ramps = {0, 2};
  c.world.prep_fraction = 0.0;
  c.world.horizon = 100;
  c.rules.penalize_objects_out = false;
  c.num_envs = envs;
  return c;
}

Spawn agent(double x, double y, double z = physics::kAgentRadius) {
  return Spawn{x, y, z, 0.3, 0.3, 0.3};
}
Spawn cube(double x, double y) {
  return Spawn{x, y, 0.25, 0.5, 0.5, 0.5};
}
physics::StaticBox wall_x(double cx, double cy, double half_len) {
  return physics::StaticBox{cx, cy, 0.25, 0.05, half_len, 0.25};
}

Scene scene_of(std::vector<Spawn> hiders, std::vector<Spawn> seekers, std::vector<Spawn> boxes = {},
               std::vector<physics::StaticBox> walls = {}) {
  Scene s;
  s.num_hiders = int(hiders.size());
  s.num_seekers = int(seekers.size());
  s.agents = hiders;
  s.agents.insert(s.agents.end(), seekers.begin(), seekers.end());
  s.boxes = boxes;
  s.wall_boxes = walls;
  return s;
}

uint8_t sees(const BatchSim& sim, int env, int viewer, int target) {
  const int A = sim.layout().max_agents;
  return sim.state().vis_agents[(size_t(env) * A + viewer) * A + target];
}

// Agents spawn facing -y. A seeker north of a hider (so looking at it) sees it; a wall between blocks it.
TEST(BatchVision, WallBetweenAgentsBlocksSight) {
  BatchSim sim(test_config());
  sim.load_scene(0, scene_of({agent(3.0, 1.0)}, {agent(3.0, 4.0)}));
  EXPECT_EQ(sees(sim, 0, 1, 0), 1) << "seeker looks straight at the hider";
  EXPECT_EQ(sees(sim, 0, 0, 1), 0) << "the hider faces away";
  sim.load_scene(0, scene_of({agent(3.0, 1.0)}, {agent(3.0, 4.0)}, {},
                             {physics::StaticBox{3.0, 2.5, 0.25, 1.0, 0.05, 0.25}}));
  EXPECT_EQ(sees(sim, 0, 1, 0), 0) << "a 0.5 m wall between them blocks sight";
}

TEST(BatchVision, AgentOnBoxSeesOverHalfMetreWall) {
  BatchSim sim(test_config());
  // The seeker stands on a cube (centre 0.65 m) right behind a wall; the hider is on the floor beyond it.
  const physics::StaticBox wall{3.0, 3.2, 0.25, 1.0, 0.05, 0.25};
  sim.load_scene(0, scene_of({agent(3.0, 1.5)}, {agent(3.0, 3.5, 0.65)}, {cube(3.0, 3.5)}, {wall}));
  EXPECT_EQ(sees(sim, 0, 1, 0), 1);
  sim.load_scene(0, scene_of({agent(3.0, 1.5)}, {agent(3.0, 3.5)}, {}, {wall}));
  EXPECT_EQ(sees(sim, 0, 1, 0), 0) << "from the floor the wall hides the hider";
}

TEST(BatchVision, TargetSeventyDegreesOffFacingIsOutsideCone) {
  BatchSim sim(test_config());
  auto at = [](double deg) {  // 2 m from (3, 4) at `deg` off the facing direction -y
    const double a = -kPi / 2 + deg * kPi / 180;
    return agent(3.0 + 2 * std::cos(a), 4.0 + 2 * std::sin(a));
  };
  sim.load_scene(0, scene_of({at(70)}, {agent(3.0, 4.0)}));
  EXPECT_EQ(sees(sim, 0, 1, 0), 0);
  sim.load_scene(0, scene_of({at(60)}, {agent(3.0, 4.0)}));
  EXPECT_EQ(sees(sim, 0, 1, 0), 1);
  sim.load_scene(0, scene_of({at(-65)}, {agent(3.0, 4.0)}));
  EXPECT_EQ(sees(sim, 0, 1, 0), 1);
}

// One agent (slot 0, a hider) in front of the sloped side of a ramp at (3, 3) turned by `ramp_yaw`: on the
// floor, within grab range, facing the ramp's centre up to `max_off` rad off. A seeker stands far away.
struct SlopeView {
  double ramp_yaw, local_x, local_y, off;
};
SlopeView random_slope_view(physics::Rng& rng, double max_off) {
  // The slope rises toward the ramp's -y; on its +y side an agent centre at local y >= 0.32 clears the
  // slope and stays within 0.25 m of the reach cuboid (half extent 0.25 along y) up to local y = 0.5.
  return SlopeView{rng.uniform(-kPi, kPi), rng.uniform(-0.15, 0.15), rng.uniform(0.33, 0.47),
                   rng.uniform(-max_off, max_off)};
}
void stage_slope_view(BatchSim& sim, const SlopeView& v) {
  Scene scene = scene_of({agent(1.0, 1.0)}, {agent(5.5, 5.5)});
  scene.ramps = {Spawn{3.0, 3.0, 0.25, 0.5, 0.5, 0.5}};
  sim.load_scene(0, scene);
  physics::World& world = sim.mutable_world(0);
  world.set_ramp_pose(0, 3.0, 3.0, 0.25, v.ramp_yaw);
  const double c = std::cos(v.ramp_yaw), s = std::sin(v.ramp_yaw);
  const double ax = 3.0 + c * v.local_x - s * v.local_y, ay = 3.0 + s * v.local_x + c * v.local_y;
  // Facing (sin yaw, -cos yaw) toward the ramp's centre, turned by `off`.
  const double agent_yaw = std::atan2(3.0 - ax, -(3.0 - ay)) + v.off;
  world.set_agent_pose(0, ax, ay, physics::kAgentRadius, agent_yaw);
  sim.resync(0);
}

// A ramp seen from its sloped side, in range and in the cone, is seen: in every one of 200 random poses.
TEST(BatchVision, RampSeenFromItsSlopedSideInEveryPose) {
  BatchSim sim(test_config());
  physics::Rng rng(21, 0, 0);
  int unseen = 0;
  for (int k = 0; k < 200; ++k) {
    stage_slope_view(sim, random_slope_view(rng, 0.9));
    unseen += sim.state().vis_ramps[0] == 0;
  }
  EXPECT_EQ(unseen, 0) << unseen << " of 200 views of the slope missed the ramp";
}

// An agent that grabs a ramp from its sloped side and walks backwards pulls it along for 12 steps, in each
// of 20 random poses (grab needs the last step's vision, so one unseen step drops the ramp).
TEST(BatchVision, RampGrabbedFromItsSlopedSideStaysHeldWhileWalkingBackwards) {
  BatchSim sim(test_config());
  physics::Rng rng(22, 0, 0);
  std::vector<AgentAction> acts(sim.layout().max_agents);
  for (int k = 0; k < 20; ++k) {
    const SlopeView v = random_slope_view(rng, 0.5);
    stage_slope_view(sim, v);
    const physics::BodyState a = sim.world(0).agent_state(0);
    // Away from the ramp: against the facing direction, in world-frame force bins.
    const double fx = a.sin_yaw, fy = -a.cos_yaw;
    acts[0] = AgentAction{uint8_t(std::lround(5 - 5 * fx)), uint8_t(std::lround(5 - 5 * fy)), 5, 1, 0};
    const double start_x = sim.state().ramp_pos[0], start_y = sim.state().ramp_pos[1];
    for (int step = 0; step < 12; ++step) {
      sim.step(acts);
      ASSERT_EQ(sim.world(0).agent_holding(0), 0)
          << "pose " << k << " (ramp yaw " << v.ramp_yaw << "), released at step " << step + 1;
    }
    EXPECT_GT(std::hypot(sim.state().ramp_pos[0] - start_x, sim.state().ramp_pos[1] - start_y), 1.0)
        << "the ramp came along, pose " << k;
  }
}

TEST(BatchLidar, ReadsDistanceToWallAndRange) {
  BatchSim sim(test_config());
  sim.load_scene(0, scene_of({agent(1.0, 3.0)}, {agent(5.5, 0.5)}, {}, {wall_x(3.0, 3.0, 1.0)}));
  const float* lidar = sim.state().lidar.data();
  EXPECT_NEAR(lidar[0], 1.95f, 1e-5) << "ray 0 along +x hits the wall face at x = 2.95";
  EXPECT_FLOAT_EQ(lidar[15], 6.0f) << "ray 15 along -x sees nothing within 6 m";
}

// Boxes and ramps seen by an agent feed the world's grab and lock.
TEST(BatchVision, ObjectVisibilityDrivesGrab) {
  BatchSim sim(test_config());
  sim.load_scene(0, scene_of({agent(3.0, 3.0)}, {agent(1.0, 5.0)}, {cube(3.0, 2.58)}));
  ASSERT_EQ(sim.state().vis_boxes[0], 1);
  std::vector<AgentAction> acts(sim.layout().max_agents);
  acts[0].grab = 1;
  sim.step(acts);
  EXPECT_EQ(sim.world(0).agent_holding(0), 0);
}

TEST(BatchRewards, HidersPenalisedWhenSeenSeekersRewarded) {
  BatchSim sim(test_config());
  const std::vector<AgentAction> idle(sim.layout().max_agents);
  sim.load_scene(0, scene_of({agent(3.0, 1.0)}, {agent(3.0, 4.0)}));
  sim.step(idle);
  EXPECT_EQ(sim.state().reward[0], -1.0f);
  EXPECT_EQ(sim.state().reward[1], 1.0f);
  // Hidden behind a wall: hiders +1, seekers -1.
  sim.load_scene(0, scene_of({agent(3.0, 1.0)}, {agent(3.0, 4.0)}, {},
                             {physics::StaticBox{3.0, 2.5, 0.25, 1.0, 0.05, 0.25}}));
  sim.step(idle);
  EXPECT_EQ(sim.state().reward[0], 1.0f);
  EXPECT_EQ(sim.state().reward[1], -1.0f);
}

TEST(BatchRewards, ZeroDuringPreparation) {
  BatchConfig config = test_config();
  config.world.prep_fraction = 0.4;
  config.world.horizon = 10;  // prep = 4 steps
  BatchSim sim(config);
  const std::vector<AgentAction> idle(sim.layout().max_agents);
  sim.load_scene(0, scene_of({agent(3.0, 1.0)}, {agent(3.0, 4.0)}));
  for (int k = 0; k < 4; ++k) {
    sim.step(idle);
    EXPECT_EQ(sim.state().reward[0], 0.0f) << "step " << k + 1;
    EXPECT_EQ(sim.state().reward[1], 0.0f);
  }
  sim.step(idle);
  EXPECT_EQ(sim.state().reward[0], -1.0f);
}

TEST(BatchRewards, OutOfBoundsReplacesReward) {
  BatchConfig config = test_config();
  config.rules.restrict_rect[0] = 0.1;
  config.rules.restrict_rect[2] = 5.9;
  BatchSim sim(config);
  const std::vector<AgentAction> idle(sim.layout().max_agents);
  // The hider is hidden (behind the seeker), but stands outside the play area.
  sim.load_scene(0, scene_of({agent(0.05, 5.0)}, {agent(3.0, 4.0)}));
  sim.step(idle);
  EXPECT_EQ(sim.state().reward[0], -10.0f);
  EXPECT_EQ(sim.state().reward[1], -1.0f);
  // Quadrant rule: a box out of bounds costs everyone -10.
  config.rules.penalize_objects_out = true;
  BatchSim quadrant(config);
  quadrant.load_scene(0, scene_of({agent(2.0, 5.0)}, {agent(3.0, 4.0)}, {cube(6.5, 3.0)}));
  quadrant.step(idle);
  EXPECT_EQ(quadrant.state().reward[0], -10.0f);
  EXPECT_EQ(quadrant.state().reward[1], -10.0f);
}

// Joint zero-sum in 2 v 2 (docs/game.md §5.1): one seeker sees one hider, the other seeker sees nobody and
// the other hider is unseen. Every hider gets -1 and every seeker +1; selfish rewards would give the unseen
// hider +1 and the blind seeker -1, team means 0 to everyone.
TEST(BatchRewards, JointZeroSumInTwoVersusTwo) {
  BatchSim sim(test_config());
  sim.load_scene(0, scene_of({agent(3.0, 1.0), agent(1.0, 5.0)}, {agent(3.0, 4.0), agent(5.0, 4.0)}));
  sim.mutable_world(0).set_agent_pose(3, 5.0, 4.0, physics::kAgentRadius, kPi);  // seeker 1 faces +y
  sim.resync(0);
  const std::vector<AgentAction> idle(sim.layout().max_agents);
  sim.step(idle);
  ASSERT_EQ(sees(sim, 0, 2, 0), 1) << "seeker 0 sees hider 0";
  ASSERT_EQ(sees(sim, 0, 2, 1), 0) << "but not hider 1";
  ASSERT_EQ(sees(sim, 0, 3, 0) + sees(sim, 0, 3, 1), 0) << "seeker 1 sees nobody";
  const float* r = sim.state().reward.data();
  EXPECT_EQ(r[0], -1.0f);
  EXPECT_EQ(r[1], -1.0f) << "the unseen hider shares its team's loss";
  EXPECT_EQ(r[2], 1.0f);
  EXPECT_EQ(r[3], 1.0f) << "the blind seeker shares its team's win";
}

// Lock features (you / your team / anyone locked it), box sizes and ramp rows, staged: hider 0 locks an
// x-elongated box, seeker 0 locks the ramp, a cube stays unlocked.
TEST(BatchObservations, LockFeaturesSizesAndRampRows) {
  BatchSim sim(test_config());
  Scene scene = scene_of({agent(3.0, 3.0), agent(5.0, 5.5)}, {agent(1.0, 4.6), agent(5.0, 1.0)},
                         {Spawn{3.0, 2.755, 0.25, 1.65, 0.15, 0.5}, cube(5.0, 3.0)});
  scene.ramps = {Spawn{1.0, 4.2, 0.25, 0.5, 0.5, 0.5}};
  sim.load_scene(0, scene);
  const Layout& L = sim.layout();
  std::vector<AgentAction> acts(L.max_agents);
  acts[0].lock = 1;  // hider 0, facing the box 0.17 m ahead
  acts[2].lock = 1;  // seeker 0, facing the ramp's slope
  sim.step(acts);
  ASSERT_TRUE(sim.world(0).object_locked(0));
  ASSERT_TRUE(sim.world(0).object_locked(2));
  const BatchState& st = sim.state();
  // Per agent (hider 0, hider 1, seeker 0, seeker 1): box 0's and the ramp's (you, team, anyone).
  const float box_lock[4][3] = {{1, 1, 1}, {0, 1, 1}, {0, 0, 1}, {0, 0, 1}};
  const float ramp_lock[4][3] = {{0, 0, 1}, {0, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  for (int a = 0; a < 4; ++a) {
    const float* box0 = &st.obs_boxes[(size_t(a) * L.max_boxes + 0) * Layout::kBoxFeatures];
    const float* box1 = &st.obs_boxes[(size_t(a) * L.max_boxes + 1) * Layout::kBoxFeatures];
    const float* ramp = &st.obs_ramps[(size_t(a) * L.max_ramps + 0) * Layout::kRampFeatures];
    const float* pad = &st.obs_ramps[(size_t(a) * L.max_ramps + 1) * Layout::kRampFeatures];
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(box0[12 + k], box_lock[a][k]) << "agent " << a << " box lock feature " << k;
      EXPECT_EQ(box1[12 + k], 0.0f) << "agent " << a << " unlocked cube, feature " << k;
      EXPECT_EQ(ramp[9 + k], ramp_lock[a][k]) << "agent " << a << " ramp lock feature " << k;
    }
    EXPECT_FLOAT_EQ(box0[9], 1.65f);
    EXPECT_FLOAT_EQ(box0[10], 0.15f);
    EXPECT_FLOAT_EQ(box0[11], 0.5f);
    EXPECT_FLOAT_EQ(box1[9], 0.5f);
    EXPECT_FLOAT_EQ(box1[10], 0.5f);
    // The ramp row: bounding-box centre, (cos, sin) of yaw 0, velocities (pinned: zero).
    EXPECT_NEAR(ramp[0], 1.0f, 1e-3);
    EXPECT_NEAR(ramp[1], 4.2f, 1e-3);
    EXPECT_NEAR(ramp[2], 0.25f, 1e-3);
    EXPECT_NEAR(ramp[3], 1.0f, 1e-6);
    EXPECT_NEAR(ramp[4], 0.0f, 1e-6);
    for (int k = 5; k < 9; ++k) EXPECT_EQ(ramp[k], 0.0f) << "a locked ramp is still, feature " << k;
    for (int k = 0; k < Layout::kRampFeatures; ++k) EXPECT_EQ(pad[k], 0.0f) << "padding ramp row";
    EXPECT_EQ(st.value_mask_ramps[a * L.max_ramps + 0], 1);
    EXPECT_EQ(st.value_mask_ramps[a * L.max_ramps + 1], 0);
  }
  EXPECT_EQ(st.mask_ramps[2 * L.max_ramps], 1) << "seeker 0 sees the ramp it locked";
  EXPECT_EQ(st.mask_boxes[0], 1) << "hider 0 sees the box it locked";
}

// prep_obs (docs/game.md §4.3) = t / (prep + 1e-5): below 1 through the preparation phase, exactly 1 from
// step prep + 1; in every agent's own and other-agent rows.
TEST(BatchObservations, PrepObservationReachesOneAfterStepPrepPlusOne) {
  BatchConfig config = test_config();
  config.world.prep_fraction = 0.4;
  config.world.horizon = 10;  // prep = 4 steps
  BatchSim sim(config);
  sim.load_scene(0, scene_of({agent(1.0, 1.0), agent(2.0, 1.0)}, {agent(3.0, 1.0), agent(4.0, 1.0)}));
  const std::vector<AgentAction> idle(sim.layout().max_agents);
  const Layout& L = sim.layout();
  for (int t = 0; t <= 7; ++t) {
    if (t > 0) sim.step(idle);
    for (int a = 0; a < 4; ++a) {
      const float self = sim.state().obs_self[a * Layout::kSelfFeatures + 10];
      const float other = sim.state().obs_agents[(size_t(a) * L.others) * Layout::kAgentFeatures + 10];
      if (t <= 4) {
        EXPECT_NEAR(self, t / 4.0, 1e-5) << "after step " << t;
        EXPECT_LT(self, 1.0f) << "after step " << t;
      } else {
        EXPECT_EQ(self, 1.0f) << "after step " << t;
      }
      EXPECT_EQ(self, other);
    }
  }
  // A long preparation phase (800 steps): t / (800 + 1e-5) rounds to 1 in float at t = 800, but prep_obs
  // must still read below 1 there.
  config.world.horizon = 2000;
  BatchSim long_prep(config);
  long_prep.load_scene(0, scene_of({agent(1.0, 1.0)}, {agent(3.0, 1.0)}));
  for (int t = 1; t <= 801; ++t) {
    long_prep.step(idle);
    const float self = long_prep.state().obs_self[10];
    if (t == 800) {
      EXPECT_LT(self, 1.0f) << "after step 800";
    } else if (t == 801) {
      EXPECT_EQ(self, 1.0f) << "after step 801";
    }
  }
}

// The docs/game.md §7 preparation statistics are taken when prep_obs first reads 1, after step prep + 1 (the
// last step whose actions were chosen while prep_obs was below 1): a box moved during that step counts, a box
// moved during the next one does not (but counts at the episode's end).
TEST(BatchEpisodes, PrepStatisticsTakenAfterStepPrepPlusOne) {
  for (const int moved_in_step : {5, 6}) {
    BatchConfig config = test_config();
    config.world.prep_fraction = 0.4;
    config.world.horizon = 10;  // prep = 4 steps, statistics after step 5
    BatchSim sim(config);
    sim.load_scene(0, scene_of({agent(1.0, 1.0)}, {agent(5.0, 5.0)}, {cube(3.0, 3.0)}));
    const std::vector<AgentAction> idle(sim.layout().max_agents);
    for (int step = 1; step <= 10; ++step) {
      if (step == moved_in_step) sim.mutable_world(0).set_box_pose(0, 3.0, 4.0, 0.25, 0.0);
      sim.step(idle);
    }
    ASSERT_EQ(sim.finished().size(), 1u);
    const EpisodeStats& st = sim.finished()[0];
    EXPECT_NEAR(st.max_box_move_prep, moved_in_step == 5 ? 1.0f : 0.0f, 0.01)
        << "moved in step " << moved_in_step;
    EXPECT_NEAR(st.max_box_move, 1.0f, 0.01);
  }
}

// The batch's rays see the arms too: a lidar ray that passes 0.17 m from an agent raised to 0.22 m (clear of
// its body sphere) stops at its arm, and that arm hides a hider behind it from a seeker.
TEST(BatchVision, ArmsBlockSightAndLidar) {
  BatchSim sim(test_config());
  for (const double yaw : {-kPi / 3, kPi}) {
    // Seeker (slot 2) at (1, 3) faces +x (yaw π/2); hider 0 at (4, 3); hider 1 raised at (2.5, 3.17): at yaw
    // -60° its right arm reaches down to y = 3.02 at z = 0.17, across the line at y = 3; at yaw 180° both
    // arms point away from it.
    sim.load_scene(0, scene_of({agent(4.0, 3.0), agent(2.5, 3.17)}, {agent(1.0, 3.0)}));
    physics::World& world = sim.mutable_world(0);
    world.set_agent_pose(2, 1.0, 3.0, physics::kAgentRadius, kPi / 2);
    world.set_agent_pose(1, 2.5, 3.17, 0.22, yaw);
    sim.resync(0);
    const bool blocked = yaw < 0;
    const int seeker = 2;
    EXPECT_EQ(sees(sim, 0, seeker, 0), blocked ? 0 : 1) << "yaw " << yaw;
    const float ray0 = sim.state().lidar[seeker * Layout::kLidar + 0];  // along +x
    if (blocked) {
      EXPECT_NEAR(ray0, 2.5 - 1.0 - std::sqrt(0.05 * 0.05 - 2 * 0.02 * 0.02), 1e-3) << "stops at the arm";
    } else {
      EXPECT_NEAR(ray0, 4.0 - 0.15 - 1.0, 1e-3) << "reaches hider 0";
    }
  }
}

TEST(BatchEpisodes, AutoResetReportsStatisticsAndStartsNextEpisode) {
  BatchConfig config;
  config.world = physics::WorldConfig::quadrant();
  config.world.horizon = 5;
  config.num_envs = 3;
  BatchSim sim(config);
  std::vector<AgentAction> acts(size_t(sim.num_envs()) * sim.layout().max_agents);
  for (int k = 0; k < 4; ++k) {
    sim.step(acts);
    EXPECT_TRUE(sim.finished().empty());
    EXPECT_EQ(sim.state().done[0], 0);
  }
  sim.step(acts);
  ASSERT_EQ(sim.finished().size(), 3u);
  for (int e = 0; e < 3; ++e) {
    EXPECT_EQ(sim.finished()[e].env, e);
    EXPECT_EQ(sim.finished()[e].episode, 0);
    EXPECT_EQ(sim.finished()[e].length, 5);
    EXPECT_EQ(sim.state().done[e], 1);
    EXPECT_EQ(sim.state().episode[e], 1) << "the env moved on to its next episode";
    EXPECT_EQ(sim.state().step_count[e], 0);
    EXPECT_EQ(sim.world(e).step_count(), 0);
  }
  sim.step(acts);
  EXPECT_TRUE(sim.finished().empty());
  EXPECT_EQ(sim.state().done[0], 0);
}

TEST(BatchEpisodes, PrepStatisticsSeeBoxMovedDuringPrep) {
  BatchConfig config = test_config();
  config.world.prep_fraction = 0.5;
  config.world.horizon = 8;
  BatchSim sim(config);
  sim.load_scene(0, scene_of({agent(2.0, 3.0)}, {agent(5.0, 5.0)}, {cube(2.45, 3.0)}));
  std::vector<AgentAction> acts(sim.layout().max_agents);
  acts[0].move_x = 10;  // the hider pushes the cube along +x during prep
  for (int k = 0; k < 8; ++k) sim.step(acts);
  ASSERT_EQ(sim.finished().size(), 1u);
  const EpisodeStats& st = sim.finished()[0];
  EXPECT_GT(st.max_box_move_prep, 0.5f);
  EXPECT_GE(st.max_box_move, st.max_box_move_prep);
  EXPECT_EQ(st.num_box_lock, 0.0f);
}

// Other agents appear in circulant order i-1, i-2, ... (docs/game.md §4.4); empty slots are zero with mask 0.
TEST(BatchObservations, CirculantOrderAndPaddingMasks) {
  BatchSim sim(test_config());
  sim.load_scene(0, scene_of({agent(1.0, 1.0), agent(2.0, 1.0)}, {agent(3.0, 1.0), agent(4.0, 1.0)}));
  const Layout& L = sim.layout();
  ASSERT_EQ(L.max_agents, 4);
  const float* obs = sim.state().obs_agents.data();
  auto other_x = [&](int a, int k) { return obs[(size_t(a) * L.others + k) * Layout::kAgentFeatures]; };
  const int expected[4][3] = {{3, 2, 1}, {0, 3, 2}, {1, 0, 3}, {2, 1, 0}};
  for (int a = 0; a < 4; ++a) {
    for (int k = 0; k < 3; ++k) EXPECT_FLOAT_EQ(other_x(a, k), 1.0f + expected[a][k]) << a << "," << k;
  }
  // Self features: position, (cos, sin) of yaw 0, hider bit.
  const float* self = sim.state().obs_self.data() + Layout::kSelfFeatures * 2;
  EXPECT_FLOAT_EQ(self[0], 3.0f);
  EXPECT_FLOAT_EQ(self[3], 1.0f);
  EXPECT_FLOAT_EQ(self[4], 0.0f);
  EXPECT_FLOAT_EQ(self[9], 0.0f) << "agent 2 is a seeker";
  // With 1 hider and 1 seeker the remaining slots are padding.
  sim.load_scene(0, scene_of({agent(1.0, 1.0)}, {agent(3.0, 1.0)}));
  EXPECT_EQ(sim.state().value_mask_agents[0], 1);
  EXPECT_EQ(sim.state().value_mask_agents[1], 0);
  EXPECT_EQ(sim.state().value_mask_agents[2], 0);
  EXPECT_FLOAT_EQ(other_x(0, 1), 0.0f);
  for (int b = 0; b < L.max_boxes; ++b) EXPECT_EQ(sim.state().value_mask_boxes[b], 0);
  for (int a = 2; a < 4; ++a) EXPECT_FLOAT_EQ(sim.state().obs_self[a * Layout::kSelfFeatures], 0.0f);
}

// Changing a seen box into an unseen one changes only the policy mask, not the value mask.
TEST(BatchObservations, PolicyMaskFollowsVisionValueMaskFollowsExistence) {
  BatchSim sim(test_config());
  sim.load_scene(0, scene_of({agent(3.0, 3.0)}, {agent(1.0, 5.0)}, {cube(3.0, 1.5), cube(3.0, 4.5)}));
  EXPECT_EQ(sim.state().mask_boxes[0], 1) << "ahead";
  EXPECT_EQ(sim.state().mask_boxes[1], 0) << "behind";
  EXPECT_EQ(sim.state().value_mask_boxes[0], 1);
  EXPECT_EQ(sim.state().value_mask_boxes[1], 1);
  const float* box1 = sim.state().obs_boxes.data() + Layout::kBoxFeatures;
  EXPECT_FLOAT_EQ(box1[1], 4.5f) << "unseen boxes still carry their features for the value function";
}

// A body thrown far out of the world (as an exploding simulation would) resets that env only.
TEST(BatchEpisodes, NumericalTroubleResetsOnlyThatEnv) {
  BatchConfig config = test_config(2);
  BatchSim sim(config);
  const std::vector<AgentAction> idle(size_t(sim.num_envs()) * sim.layout().max_agents);
  sim.step(idle);
  const int other_steps = sim.state().step_count[1];
  sim.mutable_world(0).set_agent_pose(0, 500.0, 3.0, 0.15, 0.0);
  sim.step(idle);
  ASSERT_EQ(sim.finished().size(), 1u);
  EXPECT_TRUE(sim.finished()[0].discarded);
  EXPECT_EQ(sim.finished()[0].env, 0);
  EXPECT_EQ(sim.unstable_resets(), 1);
  EXPECT_EQ(sim.state().done[0], 1);
  EXPECT_EQ(sim.state().episode[0], 1);
  EXPECT_FALSE(sim.world(0).unstable());
  EXPECT_EQ(sim.state().done[1], 0);
  EXPECT_EQ(sim.state().step_count[1], other_steps + 1) << "the other env carries on";
}

// The double-precision reference geometry of one world with every surface moved: occluders outward by `grow`
// metres (inward if negative), the target (kind, index) by `target_grow`. An agent's arms move with it.
struct MovedOccluders {
  std::vector<physics::OrientedBox> walls, boxes;
  std::vector<physics::Wedge> ramps;
  std::vector<physics::Sphere> agents, arms;
  MovedOccluders(const physics::Occluders& occ, double grow, physics::HitKind kind = physics::HitKind::kNone,
                 int target = -1, double target_grow = 0.0)
      : walls(occ.walls.begin(), occ.walls.end()),
        boxes(occ.boxes.begin(), occ.boxes.end()),
        ramps(occ.ramps.begin(), occ.ramps.end()),
        agents(occ.agents.begin(), occ.agents.end()),
        arms(occ.arms.begin(), occ.arms.end()) {
    using physics::HitKind;
    auto by = [&](HitKind k, size_t i) { return k == kind && int(i) == target ? target_grow : grow; };
    auto box = [](physics::OrientedBox& b, double d) { b.hx += d, b.hy += d, b.hz += d; };
    for (auto& w : walls) box(w, grow);
    for (size_t i = 0; i < boxes.size(); ++i) box(boxes[i], by(HitKind::kBox, i));
    for (size_t i = 0; i < ramps.size(); ++i) ramps[i].grow = by(HitKind::kRamp, i);
    for (size_t i = 0; i < agents.size(); ++i) agents[i].r += by(HitKind::kAgent, i);
    for (size_t i = 0; i < arms.size(); ++i) arms[i].r += by(HitKind::kAgent, i / 2);
  }
  physics::Occluders view() const { return {walls, boxes, ramps, agents, arms}; }
};

// The grazing band of the float batch path: where float rounding (positions and yaw stored as floats, about
// 5e-7 m at 6 m; float ray arithmetic, a few 1e-6 m over 10 m) may legitimately flip an answer. A line of
// sight is in the band if the double-precision answer changes when every surface moves by kBand (occluders
// out and the target in, or the other way round), or if its target lies within kConeBand (in cos) of the
// vision cone's edge. A lidar reading is in the band if it lies within the double-precision readings with
// every surface moved out and in by kBand. Outside the band the two paths must agree exactly (lidar within
// 1e-4 m).
constexpr double kBand = 1e-5;      // m
constexpr double kConeBand = 1e-6;  // in cos of the angle off the facing direction

struct VisionCheck {
  int compared = 0, disagreed = 0, unexplained = 0, ramps_seen = 0, lidar_banded = 0;
};

// Compares env e's vision (agents, boxes, ramps) and lidar with the double-precision reference.
void check_env_against_reference(BatchSim& sim, int e, VisionCheck& out) {
  using physics::HitKind;
  const Layout& L = sim.layout();
  const BatchState& st = sim.state();
  physics::World& world = sim.mutable_world(e);
  const physics::Occluders occ = world.occluders();
  const MovedOccluders grown(occ, kBand), shrunk(occ, -kBand);
  for (int a = 0; a < world.num_agents(); ++a) {
    const physics::BodyState v = world.agent_state(a);
    const double c = v.cos_yaw, s = v.sin_yaw;
    auto compare = [&](HitKind kind, int index, uint8_t got) {
      const bool ref = physics::visible(occ, a, c, s, kind, index);
      ++out.compared;
      if (kind == HitKind::kRamp) out.ramps_seen += got;
      if (ref == (got != 0)) return;
      ++out.disagreed;
      double p[3], f[2];
      physics::sight_point(occ, kind, index, p);
      physics::facing_direction(c, s, f);
      const double dx = p[0] - v.pos[0], dy = p[1] - v.pos[1], len = std::hypot(dx, dy);
      const bool cone_edge =
          std::abs((dx * f[0] + dy * f[1]) / len - std::cos(physics::kVisionHalfAngle)) < kConeBand;
      const MovedOccluders hide(occ, kBand, kind, index, -kBand), show(occ, -kBand, kind, index, kBand);
      const bool grazing = physics::visible(hide.view(), a, c, s, kind, index) !=
                           physics::visible(show.view(), a, c, s, kind, index);
      if (!cone_edge && !grazing) {
        ++out.unexplained;
        ADD_FAILURE() << "env " << e << " episode " << st.episode[e] << " step " << st.step_count[e]
                      << ": agent " << a << " target kind " << int(kind) << " #" << index << " reference "
                      << ref << ", batch " << int(got);
      }
    };
    for (int j = 0; j < world.num_agents(); ++j) compare(HitKind::kAgent, j, sees(sim, e, a, j));
    for (int b = 0; b < world.num_boxes(); ++b)
      compare(HitKind::kBox, b, st.vis_boxes[(size_t(e) * L.max_agents + a) * L.max_boxes + b]);
    for (int r = 0; r < world.num_ramps(); ++r)
      compare(HitKind::kRamp, r, st.vis_ramps[(size_t(e) * L.max_agents + a) * L.max_ramps + r]);
    std::array<double, physics::kLidarRays> ref{}, near{}, far{};
    physics::lidar(occ, a, ref);
    physics::lidar(grown.view(), a, near);
    physics::lidar(shrunk.view(), a, far);
    for (int k = 0; k < physics::kLidarRays; ++k) {
      const double got = st.lidar[(size_t(e) * L.max_agents + a) * Layout::kLidar + k];
      if (std::abs(got - ref[k]) <= 1e-4) continue;
      ++out.lidar_banded;
      EXPECT_TRUE(got >= near[k] - 1e-4 && got <= far[k] + 1e-4)
          << "env " << e << " agent " << a << " lidar ray " << k << ": batch " << got << ", reference "
          << ref[k] << " (band " << near[k] << " .. " << far[k] << ")";
    }
  }
}

// The batch's float SIMD vision and lidar agree with the physics layer's double-precision reference over
// whole random episodes of both games (random grabs and locks included), outside the grazing band.
TEST(BatchVision, MatchesDoublePrecisionReferenceOutsideTheGrazingBand) {
  for (const bool full : {false, true}) {
    BatchConfig config = full ? full_scene() : quadrant_scene();
    config.num_envs = 8;
    config.seed = 9;
    BatchSim sim(config);
    physics::Rng rng(9, 1, 0);
    std::vector<AgentAction> acts(size_t(sim.num_envs()) * sim.layout().max_agents);
    VisionCheck check;
    int episodes = 0;
    const int steps = full ? 250 : 170;  // one full episode and more, or two quadrant ones and more
    for (int k = 0; k < steps; ++k) {
      for (AgentAction& a : acts) {
        a = AgentAction{uint8_t(rng.uniform_int(0, 11)), uint8_t(rng.uniform_int(0, 11)),
                        uint8_t(rng.uniform_int(0, 11)), uint8_t(rng.uniform_int(0, 2)),
                        uint8_t(rng.uniform_int(0, 2))};
      }
      sim.step(acts);
      episodes += int(sim.finished().size());
      for (int e = 0; e < sim.num_envs(); ++e) check_env_against_reference(sim, e, check);
    }
    const char* game = full ? "full" : "quadrant";
    EXPECT_GE(episodes, 8) << game;
    EXPECT_GT(check.compared, 20000) << game;
    EXPECT_GT(check.ramps_seen, 500) << game << ": ramps must be seen for the check to mean something";
    EXPECT_EQ(check.unexplained, 0) << game;
    EXPECT_LE(check.disagreed, check.compared / 1000) << game << ": grazing views are rare";
    RecordProperty(std::string(game) + "_pairs", check.compared);
    RecordProperty(std::string(game) + "_grazing", check.disagreed);
    RecordProperty(std::string(game) + "_lidar_grazing", check.lidar_banded);
  }
}

// Every field of the batch state, by name.
std::map<std::string, std::vector<uint8_t>> snapshot(const BatchSim& sim) {
  std::map<std::string, std::vector<uint8_t>> fields;
  sim.state().for_each_field([&](const char* name, std::span<const uint8_t> bytes) {
    fields[name].assign(bytes.begin(), bytes.end());
  });
  return fields;
}

// Every field of the state after `steps` seeded random steps.
std::map<std::string, std::vector<uint8_t>> run(BatchConfig config, int steps, bool serial = false) {
  BatchSim sim(config);
  physics::Rng rng(config.seed, 777, 0);
  std::vector<AgentAction> acts(size_t(sim.num_envs()) * sim.layout().max_agents);
  for (int k = 0; k < steps; ++k) {
    for (AgentAction& a : acts) {
      a = AgentAction{uint8_t(rng.uniform_int(0, 11)), uint8_t(rng.uniform_int(0, 11)),
                      uint8_t(rng.uniform_int(0, 11)), uint8_t(rng.uniform_int(0, 2)),
                      uint8_t(rng.uniform_int(0, 2))};
    }
    if (serial) {
      sim.step_range(acts, 0, sim.num_envs());
    } else {
      sim.step(acts);
    }
  }
  return snapshot(sim);
}

TEST(BatchDeterminism, SameSeedBitIdenticalForOneTwoAndFourThreads) {
  BatchConfig config = full_scene();
  config.world.horizon = 30;  // several auto-resets within the run
  config.num_envs = 8;
  config.seed = 5;
  config.threads = 1;
  const auto one = run(config, 45);
  config.threads = 2;
  const auto two = run(config, 45);
  config.threads = 4;
  const auto four = run(config, 45);
  const auto serial = run(config, 45, true);
  for (const auto& [name, bytes] : one) {
    EXPECT_EQ(bytes, two.at(name)) << name << " differs between 1 and 2 threads";
    EXPECT_EQ(bytes, four.at(name)) << name << " differs between 1 and 4 threads";
    EXPECT_EQ(bytes, serial.at(name)) << name << " differs between step() and step_range()";
  }
  config.seed = 6;
  EXPECT_NE(one.at("agent_pos"), run(config, 45).at("agent_pos")) << "another seed, another run";
}

// The simulator gives the same bits in an AVX2 and an AVX-512 build (README "Build"): a digest of every state
// field after seeded random steps of `full` and `quadrant` (auto-resets, grabs and locks included), printed;
// with HNS_EXPECT_SIM_DIGEST set (CI sets it to the other build's digest, .ci/run) it must be that one.
TEST(BatchDeterminism, DigestOfSeededRandomStepsIsTheSameInEveryBuild) {
  uint64_t digest = 0xcbf29ce484222325ULL;  // FNV-1a 64 over the fields, by name, of both games
  for (const bool full : {true, false}) {
    BatchConfig config = full ? full_scene() : quadrant_scene();
    config.world.horizon = 30;
    config.num_envs = 6;
    config.seed = 5;
    config.threads = 2;
    for (const auto& [name, bytes] : run(config, 70)) {
      for (const char c : name) digest = (digest ^ uint8_t(c)) * 0x100000001b3ULL;
      for (const uint8_t b : bytes) digest = (digest ^ b) * 0x100000001b3ULL;
    }
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(digest));
  std::printf("simulator digest: %s\n", hex);
  RecordProperty("digest", hex);
  if (const char* expected = std::getenv("HNS_EXPECT_SIM_DIGEST")) {
    EXPECT_EQ(std::string(hex), std::string(expected))
        << "the simulator's bits differ from the other build's";
  }
}

// A slice of a run's envs (one process of a data-parallel run steps envs [first_env, first_env + n)) plays
// exactly what those envs play in one batch of them all, across episode ends.
TEST(BatchDeterminism, SliceOfTheEnvsPlaysWhatTheWholeBatchPlays) {
  BatchConfig config = full_scene();
  config.world.horizon = 30;
  config.num_envs = 7;
  config.seed = 9;
  BatchSim whole(config);
  config.num_envs = 3;
  config.first_env = 4;
  BatchSim slice(config);
  const int A = whole.layout().max_agents;
  std::vector<AgentAction> all(size_t(7) * A), part(size_t(3) * A);
  for (int k = 0; k < 45; ++k) {
    for (int e = 0; e < 7; ++e) {
      physics::Rng rng(9, uint64_t(k), uint64_t(e));  // the actions of global env e at step k
      for (int a = 0; a < A; ++a) {
        all[size_t(e) * A + a] = AgentAction{uint8_t(rng.uniform_int(0, 11)), uint8_t(rng.uniform_int(0, 11)),
                                             uint8_t(rng.uniform_int(0, 11)), uint8_t(rng.uniform_int(0, 2)),
                                             uint8_t(rng.uniform_int(0, 2))};
      }
    }
    std::copy(all.begin() + 4 * A, all.end(), part.begin());
    whole.step(all);
    slice.step(part);
  }
  const auto w = snapshot(whole), p = snapshot(slice);
  for (const auto& [name, bytes] : p) {
    const std::vector<uint8_t>& full_bytes = w.at(name);
    ASSERT_EQ(full_bytes.size() % 7, 0u) << name;
    const size_t per_env = full_bytes.size() / 7;
    ASSERT_EQ(bytes.size(), 3 * per_env) << name;
    EXPECT_TRUE(std::equal(bytes.begin(), bytes.end(), full_bytes.begin() + 4 * per_env)) << name;
  }
  EXPECT_EQ(slice.state().episode[0], whole.state().episode[4]);
  EXPECT_GE(whole.state().episode[4], 1) << "the run must cross an episode end";
}

// The per-kernel benchmarks recompute one phase from the SoA mirror; that must be exactly the step's work:
// recomputing vision, lidar and observations after a step changes no byte of the state.
TEST(BatchKernels, RecomputingAPhaseReproducesTheStep) {
  BatchConfig config = full_scene();
  config.num_envs = 6;
  BatchSim sim(config);
  physics::Rng rng(9, 0, 0);
  std::vector<AgentAction> acts(size_t(sim.num_envs()) * sim.layout().max_agents);
  int seen = 0;
  for (int k = 0; k < 25; ++k) {
    for (AgentAction& a : acts) a = AgentAction{uint8_t(rng.uniform_int(0, 11)), 5, 7, 0, 0};
    sim.step(acts);
    const auto after_step = snapshot(sim);
    for (int e = 0; e < sim.num_envs(); ++e) {
      sim.compute_vision(e);
      sim.compute_lidar(e);
      sim.compute_observations(e);
    }
    const auto recomputed = snapshot(sim);
    for (const auto& [name, bytes] : after_step)
      EXPECT_EQ(bytes, recomputed.at(name)) << name << ", step " << k;
    const auto& masks = sim.state().mask_boxes;
    for (size_t i = 0; i < masks.size(); ++i) seen += masks.data()[i];
  }
  EXPECT_GT(seen, 0) << "the agents must see some boxes for the check to mean something";
}

TEST(BatchConfigTest, BadConfigurationIsRejected) {
  BatchConfig config = test_config();
  config.num_envs = 0;
  EXPECT_THROW(BatchSim{config}, physics::ConfigError);
  config = test_config();
  config.threads = 0;
  EXPECT_THROW(BatchSim{config}, physics::ConfigError);
  BatchSim sim(test_config());
  const std::vector<AgentAction> wrong(1);
  EXPECT_THROW(sim.step(wrong), std::invalid_argument);
}

}  // namespace
}  // namespace hns::batch
