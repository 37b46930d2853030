// Behaviour of one world that players of the game rely on (docs/game.md §1-§3, §14).
#include "physics/world.hpp"

#include <gtest/gtest.h>
#include <ode/ode.h>

#include <cmath>
#include <cstring>
#include <thread>

#include "physics/ode_runtime.hpp"
#include "world_test_util.hpp"

namespace hns::physics {
namespace {

using testing::agent_at;
using testing::cube_at;
using testing::move;
using testing::open_scene;
using testing::ramp_at;
using testing::test_config;
using testing::wall_at;

constexpr AgentAction kIdle{};

// docs/game.md §14.4: from rest under full force an agent reaches 4.2 / 6.3 / 7.1 / 7.4 m/s after 1-4 steps (±10 %),
// and spins at about 9 rad/s under full torque.
TEST(WorldMotion, FullForceSpeedProfileMatchesOriginal) {
  World world(test_config(), 1, 0);
  world.reset_with_scene(open_scene({agent_at(1.0, 3.0)}));
  const double expected[4] = {4.2, 6.3, 7.1, 7.4};
  for (int k = 0; k < 4; ++k) {
    const AgentAction act = move(10, 5);
    world.step({&act, 1});
    const BodyState s = world.agent_state(0);
    EXPECT_NEAR(s.vel[0], expected[k], 0.1 * expected[k]) << "after step " << k + 1;
    EXPECT_NEAR(s.vel[1], 0.0, 1e-6);
    EXPECT_NEAR(s.pos[2], kAgentRadius, 0.01) << "agent must stay on the floor";
  }
}

TEST(WorldMotion, FullTorqueSpinsAtNineRadPerSecond) {
  World world(test_config(), 1, 0);
  world.reset_with_scene(open_scene({agent_at(3.0, 3.0)}));
  const AgentAction act = move(5, 5, 10);
  for (int k = 0; k < 3; ++k) world.step({&act, 1});
  EXPECT_NEAR(world.agent_state(0).ang_vel, 9.0, 0.5);
  EXPECT_NEAR(world.agent_state(0).pos[0], 3.0, 1e-3) << "turning must not translate";
}

TEST(WorldMotion, ForcesAreInTheWorldFrame) {
  World world(test_config(), 1, 0);
  world.reset_with_scene(open_scene({agent_at(3.0, 3.0)}));
  world.set_agent_pose(0, 3.0, 3.0, kAgentRadius, 1.0);  // turned, still pushes along world +y
  const AgentAction act = move(5, 10);
  for (int k = 0; k < 3; ++k) world.step({&act, 1});
  const BodyState s = world.agent_state(0);
  EXPECT_GT(s.vel[1], 5.0);
  EXPECT_NEAR(s.vel[0], 0.0, 0.05);
}

TEST(WorldMotion, AgentPushesCube) {
  World world(test_config(), 1, 0);
  world.reset_with_scene(open_scene({agent_at(2.0, 3.0)}, {}, {cube_at(2.45, 3.0)}));
  const AgentAction act = move(10, 5);
  for (int k = 0; k < 4; ++k) world.step({&act, 1});
  const BodyState cube = world.box_state(0);
  const BodyState agent = world.agent_state(0);
  EXPECT_GT(cube.pos[0], 3.2) << "the cube must be pushed along +x";
  EXPECT_LT(agent.pos[0], cube.pos[0] - 0.25) << "the agent stays behind the cube";
  EXPECT_NEAR(cube.pos[2], 0.25, 0.02) << "the cube stays on the floor";
}

// A cube against a wall and a ramp against the cube, rising toward it: the agent drives up the ramp and
// ends up standing on the cube.
TEST(WorldMotion, AgentDrivesUpRampOntoBox) {
  World world(test_config(), 1, 0);
  Scene scene = open_scene({agent_at(2.0, 3.0)}, {}, {cube_at(3.70, 3.0)}, {ramp_at(3.2, 3.0)});
  scene.wall_boxes.push_back(wall_at(4.0, 3.0, 0.05, 1.0, kOuterWallHeight));
  world.reset_with_scene(scene);
  world.set_ramp_pose(0, 3.2, 3.0, 0.25, M_PI / 2);  // slope rises toward +x
  double max_z = 0;
  for (int k = 0; k < 40; ++k) {
    const BodyState a = world.agent_state(0);
    const AgentAction act = a.pos[0] < 3.55 ? move(10, 5) : move(5, 5);
    world.step({&act, 1});
    max_z = std::max(max_z, world.agent_state(0).pos[2]);
  }
  const BodyState agent = world.agent_state(0);
  const BodyState cube = world.box_state(0);
  EXPECT_GT(max_z, 0.6);
  EXPECT_NEAR(agent.pos[2], kBoxSize + kAgentRadius, 0.03) << "the agent rests on top of the cube";
  EXPECT_NEAR(agent.pos[0], cube.pos[0], 0.25) << "above the cube's footprint";
  EXPECT_FALSE(world.unstable());
}

// A free ramp's vertical side caps are not a way up (MuJoCo, the original's engine: the agent pushes the
// ramp aside and its centre stays below 0.22 m): an agent 1 m beside a free ramp in the arena, full force
// towards it for 25 steps, from either side and in each of four facings (its arms lead, trail or point along
// the cap), stays below 0.3 m. It climbed to 0.63 m while the rigid floor contacts turned the pushed ramp
// the wrong way, its slope towards the agent (physics_parity_test has MuJoCo's figures).
TEST(WorldMotion, AgentDoesNotClimbAFreeRampsSideCap) {
  for (const int side : {-1, 1}) {
    for (int facing = 0; facing < 4; ++facing) {
      World world(test_config(), 1, 0);
      Scene scene = open_scene({agent_at(3.0 + side, 3.0)}, {}, {}, {ramp_at(3.0, 3.0)});
      for (const double x : {-0.05, 6.05})
        scene.wall_boxes.push_back(wall_at(x, 3.0, 0.05, 3.0, kOuterWallHeight));
      for (const double y : {-0.05, 6.05})
        scene.wall_boxes.push_back(wall_at(3.0, y, 3.0, 0.05, kOuterWallHeight));
      world.reset_with_scene(scene);
      world.set_ramp_pose(0, 3.0, 3.0, 0.25, 0.0);  // caps face -x and +x
      world.set_agent_pose(0, 3.0 + side, 3.0, kAgentRadius, facing * M_PI / 2);
      const AgentAction act = move(side < 0 ? 10 : 0, 5);
      double max_z = 0;
      for (int k = 0; k < 25; ++k) {
        world.step({&act, 1});
        max_z = std::max(max_z, world.agent_state(0).pos[2]);
      }
      EXPECT_LT(max_z, 0.3) << "side " << side << ", facing " << facing;
      EXPECT_FALSE(world.unstable());
    }
  }
}

// No body passes through a 0.1 m wall at top speed.
TEST(WorldMotion, AgentAtTopSpeedDoesNotTunnelThroughWall) {
  {
    World world(test_config(), 1, 0);
    Scene scene = open_scene({agent_at(0.5, 3.0)});
    scene.wall_boxes.push_back(wall_at(3.0, 3.0, 0.05, 2.0));
    world.reset_with_scene(scene);
    const AgentAction act = move(10, 5);
    double max_x = 0;
    for (int k = 0; k < 40; ++k) {
      world.step({&act, 1});
      max_x = std::max(max_x, world.agent_state(0).pos[0]);
    }
    EXPECT_LT(max_x, 2.95 - kAgentRadius + 0.04) << "at most a few cm of transient penetration";
    EXPECT_NEAR(world.agent_state(0).pos[0], 2.95 - kAgentRadius, 0.01) << "and it rests against the wall";
    EXPECT_NEAR(world.agent_state(0).pos[2], kAgentRadius, 0.05) << "no climbing a vertical wall";
  }
}

// An agent carrying a thin box (0.15 m) at top speed into a 0.1 m wall: neither passes through.
TEST(WorldMotion, CarriedThinBoxDoesNotTunnelThroughWall) {
  World world(test_config(), 1, 0);
  const Spawn thin{1.0, 2.5, 0.25, kElongatedLong, kElongatedShort, kBoxSize};  // 0.15 m thick along y
  Scene scene = open_scene({agent_at(1.0, 2.75)}, {}, {thin});
  scene.wall_boxes.push_back(wall_at(3.0, 0.5, 3.0, 0.05));  // wall along x at y = 0.5
  world.reset_with_scene(scene);
  ASSERT_EQ(world.object_visibility()[0], 1);
  const AgentAction act = move(5, 0, 5, true);  // full force toward -y, holding the box
  double min_box_y = 10;
  for (int k = 0; k < 30; ++k) {
    world.step({&act, 1});
    min_box_y = std::min(min_box_y, world.box_state(0).pos[1]);
  }
  EXPECT_EQ(world.agent_holding(0), 0);
  EXPECT_GT(min_box_y, 0.55 + 0.5 * kElongatedShort - 0.04) << "the box stops at the wall";
  EXPECT_GT(world.agent_state(0).pos[1], 0.55) << "so does the agent";
  EXPECT_FALSE(world.unstable());
}

// A cube straight ahead of an agent that faces -y (yaw 0), within grab range.
Scene grab_scene() {
  return open_scene({agent_at(3.0, 3.0)}, {agent_at(1.0, 1.0)}, {cube_at(3.0, 2.58)});
}

// The cube's offset from the agent, in the agent's frame.
void offset_in_agent_frame(const World& world, double& local_x, double& local_y) {
  const BodyState a = world.agent_state(0), b = world.box_state(0);
  const double rel_x = b.pos[0] - a.pos[0], rel_y = b.pos[1] - a.pos[1];
  local_x = a.cos_yaw * rel_x + a.sin_yaw * rel_y;
  local_y = -a.sin_yaw * rel_x + a.cos_yaw * rel_y;
}

TEST(WorldGrab, GrabbedBoxFollowsAgentAndIsReleasedWhenBitDrops) {
  World world(test_config(), 1, 0);
  world.reset_with_scene(grab_scene());
  ASSERT_EQ(world.object_visibility()[0], 1) << "the cube is in view";
  // Grab and drive along +x: the cube comes along, keeping its offset in the agent's frame.
  AgentAction acts[2] = {move(10, 5, 5, true), kIdle};
  world.step(acts);
  ASSERT_EQ(world.agent_holding(0), 0);
  for (int k = 0; k < 6; ++k) world.step(acts);
  double local_x, local_y;
  offset_in_agent_frame(world, local_x, local_y);
  EXPECT_GT(world.box_state(0).pos[0], 4.0) << "the cube travelled with the agent";
  EXPECT_NEAR(local_x, 0.0, 0.03);
  EXPECT_NEAR(local_y, -0.42, 0.03);
  EXPECT_NEAR(std::remainder(world.box_state(0).yaw() - world.agent_state(0).yaw(), 2 * M_PI), 0.0, 0.03);
  // Come to rest, then turn in place while holding: the cube swings around and turns with the agent.
  acts[0] = move(5, 5, 5, true);
  for (int k = 0; k < 8; ++k) world.step(acts);
  const double yaw_before = world.agent_state(0).yaw();
  acts[0] = move(5, 5, 10, true);
  for (int k = 0; k < 3; ++k) world.step(acts);
  EXPECT_GT(std::abs(std::remainder(world.agent_state(0).yaw() - yaw_before, 2 * M_PI)), 0.3)
      << "the agent turned";
  offset_in_agent_frame(world, local_x, local_y);
  EXPECT_NEAR(local_x, 0.0, 0.03);
  EXPECT_NEAR(local_y, -0.42, 0.03);
  EXPECT_NEAR(std::remainder(world.box_state(0).yaw() - world.agent_state(0).yaw(), 2 * M_PI), 0.0, 0.03);
  EXPECT_EQ(world.agent_holding(0), 0);
  // Come to rest, drop the bit and drive away: the cube is released and stays behind.
  acts[0] = move(5, 5, 5, true);
  for (int k = 0; k < 8; ++k) world.step(acts);
  acts[0] = kIdle;
  world.step(acts);
  EXPECT_EQ(world.agent_holding(0), -1);
  const BodyState dropped = world.box_state(0);
  const BodyState agent = world.agent_state(0);
  const double away_x = agent.pos[0] - dropped.pos[0], away_y = agent.pos[1] - dropped.pos[1];
  acts[0] = move(away_x > 0 ? 10 : 0, away_y > 0 ? 10 : 0);
  for (int k = 0; k < 5; ++k) world.step(acts);
  EXPECT_NEAR(world.box_state(0).pos[0], dropped.pos[0], 0.15);
  EXPECT_NEAR(world.box_state(0).pos[1], dropped.pos[1], 0.15);
  const BodyState far = world.agent_state(0);
  EXPECT_GT(std::hypot(far.pos[0] - dropped.pos[0], far.pos[1] - dropped.pos[1]), 1.5);
}

TEST(WorldGrab, CannotGrabOutOfRangeOrOutOfView) {
  World world(test_config(), 1, 0);
  // Out of range: 0.5 m from the cube's face.
  world.reset_with_scene(open_scene({agent_at(3.0, 3.0)}, {}, {cube_at(3.0, 2.1)}));
  AgentAction act = move(5, 5, 5, true);
  world.step({&act, 1});
  EXPECT_EQ(world.agent_holding(0), -1);
  // In range but behind the agent (it faces -y, the cube is at +y).
  world.reset_with_scene(open_scene({agent_at(3.0, 3.0)}, {}, {cube_at(3.0, 3.42)}));
  EXPECT_EQ(world.object_visibility()[0], 0);
  world.step({&act, 1});
  EXPECT_EQ(world.agent_holding(0), -1);
}

// Lock the cube of grab_scene() with the hider (agent 0).
void lock_with_hider(World& world) {
  AgentAction acts[2] = {move(5, 5, 5, false, true), kIdle};
  world.step(acts);
  ASSERT_TRUE(world.object_locked(0));
  ASSERT_EQ(world.object_lock_team(0), int(Team::kHider));
}

TEST(WorldLock, LockedBoxDoesNotMoveWhenPushedAtFullForce) {
  World world(test_config(), 1, 0);
  world.reset_with_scene(grab_scene());
  lock_with_hider(world);
  const BodyState before = world.box_state(0);
  // The seeker pushes the cube at full force from the side; the hider keeps pressing lock.
  world.set_agent_pose(1, 2.4, 2.58, kAgentRadius, 0.0);
  AgentAction acts[2] = {move(5, 5, 5, false, true), move(10, 5)};
  for (int k = 0; k < 20; ++k) world.step(acts);
  const BodyState after = world.box_state(0);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(after.pos[i], before.pos[i]);
  EXPECT_EQ(after.yaw(), before.yaw());
  EXPECT_LT(world.agent_state(1).pos[0], 2.75 - kAgentRadius + 0.05) << "the seeker is stopped by the cube";
}

TEST(WorldLock, OnlyTheLockingTeamCanUnlock) {
  World world(test_config(), 1, 0);
  world.reset_with_scene(grab_scene());
  lock_with_hider(world);
  // The hider steps out of range; a seeker stands in range, sees the cube and does not press lock.
  world.set_agent_pose(0, 3.0, 4.5, kAgentRadius, 0.0);
  world.set_agent_pose(1, 3.0, 2.16, kAgentRadius, M_PI);  // faces +y, toward the cube
  world.update_visibility();
  ASSERT_EQ(world.object_visibility()[1 * 1 + 0], 1);
  AgentAction acts[2] = {kIdle, kIdle};
  for (int k = 0; k < 3; ++k) world.step(acts);
  EXPECT_TRUE(world.object_locked(0)) << "the seekers cannot unlock the hiders' lock";
  // The seeker presses lock: still the hiders' lock.
  acts[1] = move(5, 5, 5, false, true);
  world.step(acts);
  EXPECT_TRUE(world.object_locked(0));
  EXPECT_EQ(world.object_lock_team(0), int(Team::kHider));
  // A hider in range who sees it and does not press lock unlocks it.
  acts[1] = kIdle;
  world.set_agent_pose(0, 3.0, 3.0, kAgentRadius, 0.0);
  world.update_visibility();
  world.step(acts);
  EXPECT_FALSE(world.object_locked(0));
}

TEST(WorldLock, NeverLockedObjectHasNoVetoAndLockerIsRecorded) {
  World world(test_config(), 1, 0);
  // The seeker locks while a hider stands next to the cube, sees it and does not press lock.
  Scene scene = open_scene({agent_at(3.0, 3.0)}, {agent_at(3.0, 2.16)}, {cube_at(3.0, 2.58)});
  world.reset_with_scene(scene);
  world.set_agent_pose(1, 3.0, 2.16, kAgentRadius, M_PI);
  world.update_visibility();
  AgentAction acts[2] = {kIdle, move(5, 5, 5, false, true)};
  world.step(acts);
  EXPECT_TRUE(world.object_locked(0));
  EXPECT_EQ(world.object_locker(0), 1);
  EXPECT_EQ(world.object_lock_team(0), int(Team::kSeeker));
}

TEST(WorldLock, RampsLockOnlyWhenConfigured) {
  for (bool lock_ramps : {false, true}) {
    WorldConfig config = test_config();
    config.lock_ramps = lock_ramps;
    World world(config, 1, 0);
    world.reset_with_scene(open_scene({agent_at(3.0, 3.0)}, {}, {}, {ramp_at(3.0, 2.6)}));
    ASSERT_EQ(world.object_visibility()[0], 1);
    const AgentAction act = move(5, 5, 5, false, true);
    world.step({&act, 1});
    EXPECT_EQ(world.object_locked(0), lock_ramps);
  }
}

TEST(WorldLock, ObjectsLockedAtTheEndOfAnEpisodeArePushableInTheNext) {
  WorldConfig config = test_config();
  config.lock_ramps = true;
  World world(config, 1, 0);
  const Scene scene = open_scene({agent_at(3.0, 3.0)}, {}, {cube_at(3.0, 2.58)}, {ramp_at(3.0, 3.4)});
  world.reset_with_scene(scene);
  ASSERT_EQ(world.object_visibility()[0], 1);
  // Lock the cube; then face the ramp and lock it too.
  AgentAction lock = move(5, 5, 5, false, true);
  world.step({&lock, 1});
  ASSERT_TRUE(world.object_locked(0));
  world.set_agent_pose(0, 3.0, 3.0, kAgentRadius, M_PI);  // faces +y, toward the ramp
  world.set_box_pose(0, 1.0, 1.0, kBoxSize / 2, 0.0);     // out of range, stays locked
  world.update_visibility();
  world.step({&lock, 1});
  ASSERT_TRUE(world.object_locked(0));
  ASSERT_TRUE(world.object_locked(1));
  // A new episode on the same scene: nothing is locked, and a push at full force moves both objects.
  world.reset_with_scene(scene, 1);
  EXPECT_FALSE(world.object_locked(0));
  EXPECT_FALSE(world.object_locked(1));
  const BodyState cube0 = world.box_state(0), ramp0 = world.ramp_state(0);
  // From below the cube, push along +y: the agent drives the cube into the ramp, which gives way.
  world.set_agent_pose(0, 3.0, 2.0, kAgentRadius, 0.0);
  const AgentAction push = move(5, 10);
  for (int k = 0; k < 10; ++k) world.step({&push, 1});
  EXPECT_GT(world.box_state(0).pos[1], cube0.pos[1] + 0.1) << "the cube moves again";
  EXPECT_GT(world.ramp_state(0).pos[1], ramp0.pos[1] + 0.1) << "the ramp moves again";
}

// The seeker faces a cube 0.17 m ahead (in view, within grab and lock range) and presses move, turn, grab
// and lock throughout: nothing happens during preparation; the first step after it grabs and locks.
TEST(WorldPrep, SeekersCannotActDuringPreparation) {
  WorldConfig config = test_config(0.4);
  config.horizon = 10;  // prep = steps 1..4
  World world(config, 1, 0);
  world.reset_with_scene(open_scene({agent_at(1.0, 1.0)}, {agent_at(3.0, 4.0)}, {cube_at(3.0, 3.58)}));
  ASSERT_EQ(config.prep_steps(), 4);
  const AgentAction acts[2] = {move(10, 5), move(10, 5, 10, true, true)};
  for (int k = 0; k < 4; ++k) {
    EXPECT_TRUE(world.in_prep_phase());
    ASSERT_EQ(world.object_visibility()[1], 1) << "the seeker sees the cube, step " << k + 1;
    world.step(acts);
    EXPECT_EQ(world.agent_holding(1), -1) << "step " << k + 1;
    EXPECT_FALSE(world.object_locked(0)) << "step " << k + 1;
  }
  EXPECT_GT(world.agent_state(0).pos[0], 2.0) << "the hider moves in prep";
  EXPECT_NEAR(world.agent_state(1).pos[0], 3.0, 1e-6) << "the seeker does not";
  EXPECT_NEAR(world.agent_state(1).ang_vel, 0.0, 1e-6);
  EXPECT_FALSE(world.in_prep_phase());
  world.step(acts);
  EXPECT_EQ(world.agent_holding(1), 0) << "after prep the same bits grab";
  EXPECT_TRUE(world.object_locked(0)) << "and lock";
  EXPECT_EQ(world.object_lock_team(0), int(Team::kSeeker));
}

// Ramps are objects after the boxes of the episode, not after the configured maximum: with 1 box of at most
// 4, grabbing pulls the ramp and locking pins it.
TEST(WorldGrab, RampGrabbedAndLockedWithFewerBoxesThanTheMaximum) {
  WorldConfig config = test_config();
  config.lock_ramps = true;
  World world(config, 1, 0);
  const Scene scene = open_scene({agent_at(3.0, 3.4)}, {}, {cube_at(1.0, 1.0)}, {ramp_at(3.0, 3.0)});
  world.reset_with_scene(scene);
  ASSERT_EQ(world.object_visibility()[1], 1) << "the agent faces the ramp's slope";
  const AgentAction pull = move(5, 10, 5, true);  // backwards, along +y, holding
  for (int k = 0; k < 5; ++k) world.step({&pull, 1});
  EXPECT_EQ(world.agent_holding(0), 1);
  EXPECT_GT(world.ramp_state(0).pos[1], 4.0) << "the ramp came along";
  EXPECT_NEAR(world.box_state(0).pos[0], 1.0, 1e-6) << "the box did not";
  // Lock it where it stands, then push it at full force from its slope side: it does not move.
  world.reset_with_scene(scene, 1);
  const AgentAction lock = move(5, 5, 5, false, true);
  world.step({&lock, 1});
  ASSERT_TRUE(world.object_locked(1));
  const BodyState before = world.ramp_state(0);
  const AgentAction push = move(5, 0, 5, false, true);
  for (int k = 0; k < 10; ++k) world.step({&push, 1});
  EXPECT_EQ(world.ramp_state(0).pos[1], before.pos[1]);
  EXPECT_EQ(world.ramp_state(0).pos[0], before.pos[0]);
}

// Grab and lock reach a ramp through the cuboid of docs/game.md §3.3, half extents (0.2357, 0.25, 0.3536) about its
// bounding-box centre: beside the ramp along its x axis, 0.485 m from its centre is in range, 0.490 m not
// (a 0.25 m cube would reach both).
TEST(WorldLock, RampReachIsTheSpecCuboid) {
  WorldConfig config = test_config();
  config.lock_ramps = true;
  for (const double offset : {0.480, 0.490}) {
    World world(config, 1, 0);
    world.reset_with_scene(open_scene({agent_at(3.0 + offset, 3.0)}, {}, {}, {ramp_at(3.0, 3.0)}));
    world.set_agent_pose(0, 3.0 + offset, 3.0, kAgentRadius, -M_PI / 2);  // faces -x, toward the ramp
    world.update_visibility();
    ASSERT_EQ(world.object_visibility()[0], 1);
    const AgentAction lock = move(5, 5, 5, false, true);
    world.step({&lock, 1});
    EXPECT_EQ(world.object_locked(0), offset < 0.4857) << "agent " << offset << " m from the ramp's centre";
  }
}

// The arms (docs/game.md §1.2) widen an agent to 0.36 m across its front: facing the gap (yaw 0) it cannot drive
// through 0.33 m between two walls; turned by 90° (0.30 m across) it can.
TEST(WorldMotion, ArmsWidenTheAgent) {
  for (const double yaw : {0.0, M_PI / 2}) {
    World world(test_config(), 1, 0);
    Scene scene = open_scene({agent_at(3.0, 4.0)});
    scene.wall_boxes.push_back(wall_at(3.0 - 0.165 - 1.0, 3.0, 1.0, 0.05));  // ends at x = 2.835
    scene.wall_boxes.push_back(wall_at(3.0 + 0.165 + 1.0, 3.0, 1.0, 0.05));  // starts at x = 3.165
    world.reset_with_scene(scene);
    world.set_agent_pose(0, 3.0, 4.0, kAgentRadius, yaw);
    const AgentAction act = move(5, 2);  // toward -y at a moderate force
    for (int k = 0; k < 20; ++k) world.step({&act, 1});
    if (yaw == 0.0) {
      EXPECT_GT(world.agent_state(0).pos[1], 3.0) << "the arms catch on the walls";
    } else {
      EXPECT_LT(world.agent_state(0).pos[1], 2.0) << "sideways it slips through";
    }
    EXPECT_FALSE(world.unstable());
  }
}

// An arm is part of its agent for rays: a ray that misses the body sphere but passes through an arm hits the
// agent, and the agent's own arms never block its own rays.
TEST(WorldVision, ArmsOccludeAndCountAsTheirAgent) {
  World world(test_config(), 1, 0);
  // Viewer (seeker) at (3, 5) facing -y; target hider at (3, 1); a second hider raised to z = 0.22 (as on a
  // slope) at x = 2.83, turned by 30° so that its right arm reaches out to x = 2.98 at z = 0.17, across the
  // line of sight at z = 0.15, which passes 0.17 m from its centre, clear of its body sphere.
  world.reset_with_scene(open_scene({agent_at(3.0, 1.0), agent_at(2.83, 3.0)}, {agent_at(3.0, 5.0)}));
  Occluders occ = world.occluders();
  std::vector<Sphere> agents(occ.agents.begin(), occ.agents.end()), arms(occ.arms.begin(), occ.arms.end());
  const BodyState v = world.agent_state(2);
  for (const double yaw : {M_PI / 6, -M_PI / 6}) {
    const double centre[3] = {2.83, 3.0, 0.22};
    double arm[2][3];
    arm_centres(centre, std::cos(yaw), std::sin(yaw), arm);
    agents[1] = {centre[0], centre[1], centre[2], kAgentRadius};
    arms[2] = {arm[0][0], arm[0][1], arm[0][2], kArmRadius};
    arms[3] = {arm[1][0], arm[1][1], arm[1][2], kArmRadius};
    const Occluders moved{occ.walls, occ.boxes, occ.ramps, agents, arms};
    const bool blocked = yaw > 0;
    EXPECT_EQ(visible(moved, 2, v.cos_yaw, v.sin_yaw, HitKind::kAgent, 0), !blocked) << "yaw " << yaw;
    const double origin[3] = {3.0, 5.0, kAgentRadius}, down[3] = {0, -1, 0};
    const RayHit hit = cast_ray(moved, origin, down, 10.0, 2);
    EXPECT_EQ(hit.kind, HitKind::kAgent);
    EXPECT_EQ(hit.index, blocked ? 1 : 0) << "an arm hit reports its agent";
    // A ray from the viewer's centre through its own arm does not stop there.
    double toward_arm[3] = {arms[4].cx - origin[0], arms[4].cy - origin[1], arms[4].cz - origin[2]};
    const double len = std::sqrt(toward_arm[0] * toward_arm[0] + toward_arm[1] * toward_arm[1] +
                                 toward_arm[2] * toward_arm[2]);
    for (double& d : toward_arm) d /= len;
    EXPECT_EQ(cast_ray(moved, origin, toward_arm, 10.0, 2).kind, HitKind::kNone);
    EXPECT_EQ(cast_ray(moved, origin, toward_arm, 10.0, -1).kind, HitKind::kAgent) << "unless not skipped";
  }
}

TEST(WorldEpisode, DoneAtHorizon) {
  WorldConfig config = test_config();
  config.horizon = 3;
  World world(config, 1, 0);
  world.reset_with_scene(open_scene({agent_at(1.0, 1.0)}));
  for (int k = 0; k < 3; ++k) {
    EXPECT_FALSE(world.done());
    world.step({&kIdle, 1});
  }
  EXPECT_TRUE(world.done());
}

TEST(WorldEpisode, StepRejectsWrongActionCount) {
  World world(test_config(), 1, 0);
  world.reset_with_scene(open_scene({agent_at(1.0, 1.0)}));
  const AgentAction acts[2] = {};
  EXPECT_THROW(world.step(acts), std::invalid_argument);
}

// A trajectory fingerprint: every body's pose and velocity after each step of seeded random actions.
std::vector<double> run_trajectory(const WorldConfig& config, uint64_t seed, uint64_t world_index,
                                   int steps) {
  World world(config, seed, world_index);
  world.reset(0);
  Rng action_rng(seed, world_index + 1000, 0);
  std::vector<double> trace;
  std::vector<AgentAction> acts(world.num_agents());
  for (int k = 0; k < steps; ++k) {
    for (AgentAction& a : acts) {
      a = AgentAction{uint8_t(action_rng.uniform_int(0, 11)), uint8_t(action_rng.uniform_int(0, 11)),
                      uint8_t(action_rng.uniform_int(0, 11)), uint8_t(action_rng.uniform_int(0, 2)),
                      uint8_t(action_rng.uniform_int(0, 2))};
    }
    world.step(acts);
    auto add = [&](const BodyState& s) {
      trace.insert(trace.end(), {s.pos[0], s.pos[1], s.pos[2], s.yaw(), s.vel[0]});
    };
    for (int a = 0; a < world.num_agents(); ++a) add(world.agent_state(a));
    for (int b = 0; b < world.num_boxes(); ++b) add(world.box_state(b));
    for (int r = 0; r < world.num_ramps(); ++r) add(world.ramp_state(r));
  }
  return trace;
}

// A world reset to episode k plays it bit for bit as a fresh world does, whatever the previous episodes left
// behind (locked or sleeping objects, held ones, bodies in motion): what a resumed training run relies on.
TEST(WorldDeterminism, ResetWorldPlaysAnEpisodeAsAFreshWorldDoes) {
  for (const WorldConfig& config : {WorldConfig::quadrant(), WorldConfig::full()}) {
    World reused(config, 5, 2);
    Rng action_rng(5, 999, 0);
    std::vector<AgentAction> acts;
    // Random actions with lock and grab pressed often, so objects end episodes locked, held or asleep.
    auto act = [&](World& world) {
      acts.resize(world.num_agents());
      for (AgentAction& a : acts) {
        a = AgentAction{uint8_t(action_rng.uniform_int(0, 11)), uint8_t(action_rng.uniform_int(0, 11)),
                        uint8_t(action_rng.uniform_int(0, 11)), uint8_t(action_rng.uniform_int(0, 3) != 0),
                        uint8_t(action_rng.uniform_int(0, 3) != 0)};
      }
      world.step(acts);
    };
    int locked_at_end = 0;
    for (uint64_t episode = 0; episode < 6; ++episode) {
      reused.reset(episode);
      World fresh(config, 5, 2);
      fresh.reset(episode);
      const Rng start = action_rng;
      std::vector<double> a, b;
      auto record = [](const World& w, std::vector<double>& out) {
        auto add = [&](const BodyState& s) {
          out.insert(out.end(), {s.pos[0], s.pos[1], s.pos[2], s.cos_yaw, s.sin_yaw, s.vel[0], s.vel[1]});
        };
        for (int i = 0; i < w.num_agents(); ++i) add(w.agent_state(i));
        for (int i = 0; i < w.num_boxes(); ++i) add(w.box_state(i));
        for (int i = 0; i < w.num_ramps(); ++i) add(w.ramp_state(i));
      };
      for (int k = 0; k < config.horizon; ++k) {
        act(reused);
        record(reused, a);
      }
      action_rng = start;
      for (int k = 0; k < config.horizon; ++k) {
        act(fresh);
        record(fresh, b);
      }
      ASSERT_EQ(a.size(), b.size());
      EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(double)))
          << layout_name(config.scene.layout) << " episode " << episode << " differs after a reset";
      for (int o = 0; o < reused.num_objects(); ++o) locked_at_end += reused.object_locked(o);
    }
    EXPECT_GT(locked_at_end, 0) << "some episode must end with an object locked";
  }
}

TEST(WorldDeterminism, SameSeedGivesBitIdenticalTrajectory) {
  const WorldConfig config = WorldConfig::quadrant();
  const unsigned long long calls_before = solver_rng_calls();
  dRandSetSeed(1);
  const std::vector<double> a = run_trajectory(config, 7, 3, 40);
  EXPECT_GT(solver_rng_calls(), calls_before) << "ODE's solver must draw from the world's own stream";
  dRandSetSeed(12345);  // ODE's global seed must not matter
  const std::vector<double> b = run_trajectory(config, 7, 3, 40);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(double)));
  const std::vector<double> c = run_trajectory(config, 8, 3, 40);
  EXPECT_NE(a, c) << "another seed gives another trajectory";
}

// Two worlds stepped at once from two threads (docs/design.md "Threading and ODE": per-world threading implementation) give the
// same trajectories as stepped one after the other.
TEST(WorldDeterminism, TwoWorldsSteppedFromTwoThreadsMatchSerial) {
  const WorldConfig config = WorldConfig::full();
  const std::vector<double> serial0 = run_trajectory(config, 11, 0, 60);
  const std::vector<double> serial1 = run_trajectory(config, 11, 1, 60);
  std::vector<double> parallel0, parallel1;
  std::thread t0([&] { parallel0 = run_trajectory(config, 11, 0, 60); });
  std::thread t1([&] { parallel1 = run_trajectory(config, 11, 1, 60); });
  t0.join();
  t1.join();
  EXPECT_EQ(serial0, parallel0);
  EXPECT_EQ(serial1, parallel1);
}

TEST(WorldConfigTest, BadConfigurationGivesClearErrors) {
  auto message = [](WorldConfig config) -> std::string {
    try {
      World world(config, 1, 0);
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "";
  };
  WorldConfig config = WorldConfig::quadrant();
  config.scene.boxes = {-1, 2};
  EXPECT_NE(message(config).find("boxes"), std::string::npos);
  config = WorldConfig::quadrant();
  config.physics.substeps = 0;
  EXPECT_NE(message(config).find("physics.substeps"), std::string::npos);
  config = WorldConfig::quadrant();
  config.horizon = 0;
  EXPECT_NE(message(config).find("horizon"), std::string::npos);
  config = WorldConfig::quadrant();
  config.prep_fraction = 1.5;
  EXPECT_NE(message(config).find("prep_fraction"), std::string::npos);
}

TEST(WorldConfigTest, SceneLargerThanMaximaIsRejected) {
  World world(test_config(), 1, 0);
  Scene scene = open_scene({agent_at(1, 1)}, {},
                           {cube_at(2, 2), cube_at(3, 3), cube_at(4, 4), cube_at(5, 5), cube_at(1, 5)});
  EXPECT_THROW(world.reset_with_scene(scene), ConfigError);
}

}  // namespace
}  // namespace hns::physics
