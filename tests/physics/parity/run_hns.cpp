// The hns side of the parity suite: the stage as a hand-built scene in one World, stepped with the actions.
#include <cmath>

#include "parity/stage.hpp"
#include "physics/world.hpp"

namespace hns::parity {

using namespace physics;

Stage& Stage::with_arena() {
  for (const double x : {-0.05, 6.05}) walls.push_back(WallStart{x, 3.0, 0.05, 3.1, 4.0});
  for (const double y : {-0.05, 6.05}) walls.push_back(WallStart{3.0, y, 3.0, 0.05, 4.0});
  return *this;
}

std::vector<Frame> run_hns(const Stage& stage, int steps, const Policy& policy) {
  const int num_agents = int(stage.agents.size());
  WorldConfig c = WorldConfig::empty();
  c.scene.hiders = {num_agents, num_agents};
  c.scene.seekers = {0, 0};
  c.scene.boxes = {int(stage.boxes.size()), int(stage.boxes.size())};
  c.scene.elongated = {0, int(stage.boxes.size())};
  c.scene.ramps = {int(stage.ramps.size()), int(stage.ramps.size())};
  c.prep_fraction = 0.0;
  c.horizon = steps + 1;
  World world(c, 1, 0);

  Scene scene;
  scene.layout = Layout::kEmpty;
  scene.num_hiders = num_agents;
  scene.num_seekers = 0;
  for (const AgentStart& a : stage.agents) scene.agents.push_back(Spawn{a.x, a.y, a.z, 0.3, 0.3, 0.3});
  for (const BoxStart& b : stage.boxes) scene.boxes.push_back(Spawn{b.x, b.y, 0.5 * b.sz, b.sx, b.sy, b.sz});
  for (const RampStart& r : stage.ramps) {
    scene.ramps.push_back(Spawn{r.x, r.y, 0.5 * kRampSize, kRampSize, kRampSize, kRampSize});
  }
  for (const WallStart& w : stage.walls) {
    scene.wall_boxes.push_back(StaticBox{w.cx, w.cy, 0.5 * w.height, w.hx, w.hy, 0.5 * w.height});
  }
  world.reset_with_scene(scene);
  for (int i = 0; i < num_agents; ++i) {
    world.set_agent_pose(i, stage.agents[i].x, stage.agents[i].y, stage.agents[i].z, stage.agents[i].yaw);
  }
  for (size_t i = 0; i < stage.boxes.size(); ++i) {
    const BoxStart& b = stage.boxes[i];
    world.set_box_pose(int(i), b.x, b.y, 0.5 * b.sz, b.yaw);
  }
  for (size_t i = 0; i < stage.ramps.size(); ++i) {
    world.set_ramp_pose(int(i), stage.ramps[i].x, stage.ramps[i].y, 0.5 * kRampSize, stage.ramps[i].yaw);
  }

  auto pose = [](const BodyState& s) {
    return Pose{s.pos[0], s.pos[1], s.pos[2], std::atan2(s.sin_yaw, s.cos_yaw)};
  };
  auto frame = [&] {
    Frame f;
    for (int i = 0; i < num_agents; ++i) f.agents.push_back(pose(world.agent_state(i)));
    for (size_t i = 0; i < stage.boxes.size(); ++i) f.boxes.push_back(pose(world.box_state(int(i))));
    for (size_t i = 0; i < stage.ramps.size(); ++i) f.ramps.push_back(pose(world.ramp_state(int(i))));
    return f;
  };
  std::vector<Frame> frames;
  Frame now = frame();
  std::vector<AgentAction> actions(static_cast<size_t>(num_agents));
  for (int k = 0; k < steps; ++k) {
    const std::vector<Move> moves = policy(k, now);
    for (int i = 0; i < num_agents; ++i) {
      const Move mv = size_t(i) < moves.size() ? moves[size_t(i)] : Move{};
      actions[size_t(i)] =
          AgentAction{uint8_t(mv.x), uint8_t(mv.y), uint8_t(mv.turn), uint8_t(mv.grab), uint8_t(mv.lock)};
    }
    world.step(actions);
    now = frame();
    frames.push_back(now);
  }
  return frames;
}

}  // namespace hns::parity
