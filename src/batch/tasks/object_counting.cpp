// Object counting (the paper's §6; docs/transfer.md "Object counting"): a probe of a frozen policy's memory,
// not a game to learn. The agent is pinned facing a gap between two screens, its actions are ignored, and
// the cubes slide out of view to either side on a script (physics::counting_box_x); a head trained on the
// policy's memory must tell how many went left. The reward is 0. The scene's preset is at the end.
#include <algorithm>
#include <cmath>

#include "batch/scenes.hpp"
#include "batch/tasks/task.hpp"

namespace hns::batch {
namespace {

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

class ObjectCounting final : public SingleAgentTask {
 public:
  // Agent 0 and the counting layout, which the script poses; no construction sites, no food. (Not
  // SingleAgentTask's checks: those refuse the counting layout.)
  void validate(const physics::WorldConfig& world, const GameRules& /*rules*/) const override {
    require_agent_zero(world);
    refuse_sites(world);
    physics::check_field(world.scene.layout == physics::Layout::kCounting, "scene.layout",
                         int(world.scene.layout),
                         "the counting layout goes with the object-counting task, and only with it");
    refuse_food(world);
  }
  int hider_observation() const override { return 0; }  // a constant 0 (docs/game.md §9)
  bool scripted() const override { return true; }
  void start_episode(EnvRef& ref, uint64_t /*episode*/) const override { pose_counting(ref); }
  void after_physics(EnvRef& ref) const override { pose_counting(ref); }

 protected:
  // A supervised probe: no reward.
  void reward(EnvRef& ref, float* reward) const override { std::fill_n(reward, ref.L.max_agents, 0.0f); }
};

}  // namespace

// The paper's object counting (§6; docs/transfer.md): the fixed counting stage, 6 cubes, horizon 80.
BatchConfig object_counting_scene() {
  static const ObjectCounting task;
  BatchConfig c = transfer_scene(task, 80);
  c.world.scene.layout = physics::Layout::kCounting;
  c.world.scene.boxes = {6, 6};
  return c;
}

}  // namespace hns::batch
