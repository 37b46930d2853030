// BatchSim: vision and lidar on hand-built scenes, rewards, auto-reset, observation layout, determinism.
#include "batch/batch_sim.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
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
  c.world.penalize_objects_out = false;
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
  config.world.restrict_rect[0] = 0.1;
  config.world.restrict_rect[2] = 5.9;
  BatchSim sim(config);
  const std::vector<AgentAction> idle(sim.layout().max_agents);
  // The hider is hidden (behind the seeker), but stands outside the play area.
  sim.load_scene(0, scene_of({agent(0.05, 5.0)}, {agent(3.0, 4.0)}));
  sim.step(idle);
  EXPECT_EQ(sim.state().reward[0], -10.0f);
  EXPECT_EQ(sim.state().reward[1], -1.0f);
  // Quadrant rule: a box out of bounds costs everyone -10.
  config.world.penalize_objects_out = true;
  BatchSim quadrant(config);
  quadrant.load_scene(0, scene_of({agent(2.0, 5.0)}, {agent(3.0, 4.0)}, {cube(6.5, 3.0)}));
  quadrant.step(idle);
  EXPECT_EQ(quadrant.state().reward[0], -10.0f);
  EXPECT_EQ(quadrant.state().reward[1], -10.0f);
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

// Other agents appear in circulant order i-1, i-2, ... (SPEC §4.4); empty slots are zero with mask 0.
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

// The batch's float SIMD vision agrees with the physics layer's double-precision reference.
TEST(BatchVision, MatchesScalarReferenceOnRandomEpisodes) {
  BatchConfig config;
  config.world = physics::WorldConfig::full();
  config.num_envs = 6;
  config.seed = 9;
  BatchSim sim(config);
  physics::Rng rng(9, 1, 0);
  const Layout& L = sim.layout();
  std::vector<AgentAction> acts(size_t(sim.num_envs()) * L.max_agents);
  int compared = 0, disagreed = 0;
  for (int k = 0; k < 40; ++k) {
    for (AgentAction& a : acts) {
      a = AgentAction{uint8_t(rng.uniform_int(0, 11)), uint8_t(rng.uniform_int(0, 11)),
                      uint8_t(rng.uniform_int(0, 11)), 0, 0};
    }
    sim.step(acts);
    for (int e = 0; e < sim.num_envs(); ++e) {
      physics::World& world = sim.mutable_world(e);
      const physics::Occluders occ = world.occluders();
      for (int a = 0; a < world.num_agents(); ++a) {
        const physics::BodyState st = world.agent_state(a);
        const double c = st.cos_yaw, s = st.sin_yaw;
        for (int j = 0; j < world.num_agents(); ++j) {
          const bool ref = physics::visible(occ, a, c, s, physics::HitKind::kAgent, j);
          disagreed += ref != (sees(sim, e, a, j) != 0);
          ++compared;
        }
        for (int b = 0; b < world.num_boxes(); ++b) {
          const bool ref = physics::visible(occ, a, c, s, physics::HitKind::kBox, b);
          disagreed += ref != (sim.state().vis_boxes[(size_t(e) * L.max_agents + a) * L.max_boxes + b] != 0);
          ++compared;
        }
        std::array<double, physics::kLidarRays> lidar{};
        physics::lidar(occ, a, lidar);
        for (int r = 0; r < physics::kLidarRays; ++r) {
          EXPECT_NEAR(sim.state().lidar[(size_t(e) * L.max_agents + a) * Layout::kLidar + r], lidar[r], 2e-4);
        }
      }
    }
  }
  EXPECT_GT(compared, 3000);
  EXPECT_LE(disagreed, compared / 200) << disagreed << " of " << compared << " visibility pairs differ";
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
  BatchConfig config;
  config.world = physics::WorldConfig::full();
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

// The per-kernel benchmarks recompute one phase from the SoA mirror; that must be exactly the step's work:
// recomputing vision, lidar and observations after a step changes no byte of the state.
TEST(BatchKernels, RecomputingAPhaseReproducesTheStep) {
  BatchConfig config;
  config.world = physics::WorldConfig::full();
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
