// A staged scene for the physics parity suite: the same bodies, poses and per-step actions run in hns's World
// and in MuJoCo (the original's engine) with a model of the original's bodies and constants
// (docs/physics.md).
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace hns::parity {

struct AgentStart {
  double x, y;
  double yaw = 0;   // rad; 0 faces -y (the arms' side), as in both engines
  double z = 0.15;  // m, centre height (0.15: on the floor; 0.65: on a cube)
};
struct BoxStart {
  double x, y;
  double sx = 0.5, sy = 0.5, sz = 0.5;  // m, full extents
  double yaw = 0;
  // MuJoCo: pinned where it starts, as the original's lock pins every joint (its range set to [q, q] at run
  // time). hns locks it through the game's rule: some agent must press lock beside it (Move::lock).
  bool locked = false;
};
struct RampStart {
  double x, y;     // bounding-box centre
  double yaw = 0;  // 0: back face at -y, slope rising towards -y
};
struct WallStart {
  double cx, cy, hx, hy;  // centre and half extents in x and y (m)
  double height = 0.5;
};

// One agent's action in one env step: the movement and turn bins (0 .. 10, 5 = none) of the policy's action,
// and the grab and lock bits (hns applies its game rules: range, vision, teams).
struct Move {
  int x = 5, y = 5, turn = 5;
  bool grab = false, lock = false;
};

// MuJoCo: agent `agent` holds box `box` by the original's weld constraint while its grab bit is set, keeping
// their relative pose at the start (stage both with yaw 0). hns grabs through the game's rule.
struct Hold {
  int agent, box;
};

struct Stage {
  std::vector<AgentStart> agents;
  std::vector<BoxStart> boxes;
  std::vector<RampStart> ramps;
  std::vector<WallStart> walls;
  std::vector<Hold> holds;
  // The outer walls of the 6 x 6 m arena (4 m high, inner faces at 0 and 6).
  Stage& with_arena();
};

// Where a body is after a step: centre (agents, boxes) or bounding-box centre (ramps), and yaw.
struct Pose {
  double x, y, z, yaw;
};
struct Frame {
  std::vector<Pose> agents, boxes, ramps;
};

// The actions of every agent in step k, given the frame before it.
using Policy = std::function<std::vector<Move>(int k, const Frame& now)>;

// Runs `steps` env steps (15 substeps of 5 ms) from the stage; returns the frame after each step.
std::vector<Frame> run_hns(const Stage& stage, int steps, const Policy& policy);
std::vector<Frame> run_mujoco(const Stage& stage, int steps, const Policy& policy);

// The MJCF text run_mujoco compiles for a stage (for a reader who wants to open it in MuJoCo's viewer).
std::string mujoco_xml(const Stage& stage);

}  // namespace hns::parity
