// The box-locking transfer tasks of SPEC §9.2 on staged scenes: lock-and-return's lock, return and success
// reward; sequential-lock's order (a lock out of order is refused) and its target; the spoofed observation
// slots that let a hide-and-seek policy act in them.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "batch/batch_sim.hpp"
#include "physics/presets.hpp"

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
  BatchConfig c;
  c.world = physics::world_preset(scene);
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

TEST(TransferTasks, PresetsValidateAndPlace) {
  for (const char* name : {"lock-and-return", "sequential-lock"}) {
    physics::WorldConfig w = physics::world_preset(name);
    EXPECT_NO_THROW(w.validate()) << name;
    EXPECT_NO_THROW(w.scene.check_placeable()) << name;
    EXPECT_EQ(w.horizon, 120) << name;
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
}

}  // namespace
}  // namespace hns::batch
