// Hand-built scenes for the world tests.
#pragma once

#include <vector>

#include "physics/world.hpp"

namespace hns::physics::testing {

// A world with room for up to 4 agents, 4 boxes and 2 ramps; no preparation phase unless asked.
inline WorldConfig test_config(double prep_fraction = 0.0) {
  WorldConfig c = WorldConfig::empty();
  c.scene.hiders = {1, 2};
  c.scene.seekers = {0, 2};
  c.scene.boxes = {0, 4};
  c.scene.elongated = {0, 4};
  c.scene.ramps = {0, 2};
  c.prep_fraction = prep_fraction;
  c.horizon = 1000;
  return c;
}

inline Spawn agent_at(double x, double y) {
  return Spawn{x, y, kAgentRadius, 0.3, 0.3, 0.3};
}
inline Spawn cube_at(double x, double y) {
  return Spawn{x, y, 0.5 * kBoxSize, kBoxSize, kBoxSize, kBoxSize};
}
inline Spawn ramp_at(double x, double y) {
  return Spawn{x, y, 0.5 * kRampSize, kRampSize, kRampSize, kRampSize};
}
// A static wall box centred at (cx, cy) with the given half extents in x and y.
inline StaticBox wall_at(double cx, double cy, double hx, double hy, double height = kInteriorWallHeight) {
  return StaticBox{cx, cy, 0.5 * height, hx, hy, 0.5 * height};
}

// A scene with no walls: hiders first, then seekers.
inline Scene open_scene(std::vector<Spawn> hiders, std::vector<Spawn> seekers = {},
                        std::vector<Spawn> boxes = {}, std::vector<Spawn> ramps = {}) {
  Scene s;
  s.layout = Layout::kEmpty;
  s.num_hiders = int(hiders.size());
  s.num_seekers = int(seekers.size());
  s.agents = hiders;
  s.agents.insert(s.agents.end(), seekers.begin(), seekers.end());
  s.boxes = boxes;
  s.ramps = ramps;
  return s;
}

inline AgentAction move(int bx, int by, int turn = 5, bool grab = false, bool lock = false) {
  return AgentAction{uint8_t(bx), uint8_t(by), uint8_t(turn), uint8_t(grab), uint8_t(lock)};
}

}  // namespace hns::physics::testing
