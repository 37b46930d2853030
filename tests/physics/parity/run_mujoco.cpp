// The MuJoCo side of the parity suite: an MJCF model of the original's bodies and constants
// (docs/physics.md), compiled per stage, stepped 15 x 5 ms per env step with the actions held as motor
// controls.
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>

#include "parity/stage.hpp"

namespace hns::parity {
namespace {

constexpr int kSubsteps = 15;

// Control of a movement or turn bin: linspace(-0.9, 0.9, 11).
double ctrl(int bin) {
  return -0.9 + 0.18 * bin;
}

// Four joints per movable body (tx, ty, tz slides, rz hinge), each named PREFIX + axis.
void joints(std::ostringstream& x, const std::string& prefix, double damp_xy, double damp_z, double damp_rz) {
  x << "<joint name='" << prefix << "tx' type='slide' axis='1 0 0' damping='" << damp_xy << "'/>"
    << "<joint name='" << prefix << "ty' type='slide' axis='0 1 0' damping='" << damp_xy << "'/>"
    << "<joint name='" << prefix << "tz' type='slide' axis='0 0 1' damping='" << damp_z << "'/>"
    << "<joint name='" << prefix << "rz' type='hinge' axis='0 0 1' damping='" << damp_rz << "'/>";
}

}  // namespace

std::string mujoco_xml(const Stage& stage) {
  std::ostringstream x;
  x.precision(17);
  // MuJoCo's defaults of the original's era: Euler, pyramidal cone, Newton, solref (0.02, 1), solimp
  // (0.9, 0.95, 0.001); gravity 5 g.
  x << "<mujoco model='hns-parity'><compiler angle='radian' inertiafromgeom='true'/>"
    << "<option timestep='0.005' gravity='0 0 -50' integrator='Euler' cone='pyramidal' solver='Newton'/>"
    << "<asset><mesh name='ramp' vertex='"
    // The wedge in its bounding-box frame: bottom at z = -0.25, back face at y = -0.25, slope rising to -y.
    << "-0.25 -0.25 -0.25  0.25 -0.25 -0.25  0.25 0.25 -0.25  -0.25 0.25 -0.25  "
    << "-0.25 -0.25 0.25  0.25 -0.25 0.25'/></asset><worldbody>"
    << "<geom name='floor' type='plane' pos='3 3 0' size='3 3 0.1' friction='0.2 0.005 0.0001' condim='3'/>";
  for (const WallStart& w : stage.walls) {
    x << "<geom type='box' pos='" << w.cx << ' ' << w.cy << ' ' << 0.5 * w.height << "' size='" << w.hx << ' '
      << w.hy << ' ' << 0.5 * w.height << "' friction='0.01 0.005 0.0001' condim='3'/>";
  }
  for (size_t i = 0; i < stage.agents.size(); ++i) {
    const AgentStart& a = stage.agents[i];
    const std::string p = "agent" + std::to_string(i);
    x << "<body name='" << p << "' pos='" << a.x << ' ' << a.y << ' ' << a.z << "'>";
    joints(x, p, 10, 1, 10);
    x << "<geom type='sphere' size='0.15' mass='1' friction='0.01 0.005 0.0001' condim='3'/>"
      << "<geom type='sphere' size='0.05' pos='-0.13 -0.075 -0.05' mass='0' friction='0.01 0.005 0.0001'/>"
      << "<geom type='sphere' size='0.05' pos='0.13 -0.075 -0.05' mass='0' friction='0.01 0.005 0.0001'/>"
      << "</body>";
  }
  for (size_t i = 0; i < stage.boxes.size(); ++i) {
    const BoxStart& b = stage.boxes[i];
    const std::string p = "box" + std::to_string(i);
    x << "<body name='" << p << "' pos='" << b.x << ' ' << b.y << ' ' << 0.5 * b.sz << "'>";
    joints(x, p, 0.01, 0.01, 0.01);
    x << "<geom type='box' size='" << 0.5 * b.sx << ' ' << 0.5 * b.sy << ' ' << 0.5 * b.sz
      << "' mass='1' friction='0.2 0.005 0.0001' condim='3'/></body>";
  }
  for (size_t i = 0; i < stage.ramps.size(); ++i) {
    const RampStart& r = stage.ramps[i];
    const std::string p = "ramp" + std::to_string(i);
    x << "<body name='" << p << "' pos='" << r.x << ' ' << r.y << " 0.25'>";
    joints(x, p, 0.1, 0.1, 0.1);
    x << "<geom type='mesh' mesh='ramp' mass='1' friction='0.01 0.005 0.0001' condim='3'/></body>";
  }
  x << "</worldbody>";
  if (!stage.holds.empty()) {
    x << "<equality>";
    for (const Hold& h : stage.holds) {
      x << "<weld name='hold" << h.agent << "_" << h.box << "' body1='agent" << h.agent << "' body2='box"
        << h.box << "'/>";
    }
    x << "</equality>";
  }
  x << "<actuator>";
  for (size_t i = 0; i < stage.agents.size(); ++i) {
    const std::string p = "agent" + std::to_string(i);
    for (const char* axis : {"tx", "ty", "rz"}) {
      x << "<motor joint='" << p << axis << "' gear='100' ctrllimited='true' ctrlrange='-0.9 0.9'/>";
    }
  }
  x << "</actuator></mujoco>";
  return x.str();
}

std::vector<Frame> run_mujoco(const Stage& stage, int steps, const Policy& policy) {
  const std::string xml = mujoco_xml(stage);
  char error[1000] = "";
  auto vfs = std::make_unique<mjVFS>();  // about 2 MB: not on the stack
  mj_defaultVFS(vfs.get());
  if (mj_makeEmptyFileVFS(vfs.get(), "stage.xml", int(xml.size())) != 0)
    throw std::runtime_error("MuJoCo VFS");
  std::copy(xml.begin(), xml.end(), static_cast<char*>(vfs->filedata[vfs->nfile - 1]));
  mjModel* m = mj_loadXML("stage.xml", vfs.get(), error, sizeof error);
  mj_deleteVFS(vfs.get());
  if (m == nullptr) throw std::runtime_error(std::string("MuJoCo rejected the stage's model: ") + error);
  mjData* d = mj_makeData(m);
  auto qadr = [&](const std::string& joint) {
    const int j = mj_name2id(m, mjOBJ_JOINT, joint.c_str());
    if (j < 0) throw std::runtime_error("no joint " + joint);
    return m->jnt_qposadr[j];
  };
  // Initial yaws on the hinges.
  for (size_t i = 0; i < stage.agents.size(); ++i)
    d->qpos[qadr("agent" + std::to_string(i) + "rz")] = stage.agents[i].yaw;
  for (size_t i = 0; i < stage.boxes.size(); ++i)
    d->qpos[qadr("box" + std::to_string(i) + "rz")] = stage.boxes[i].yaw;
  for (size_t i = 0; i < stage.ramps.size(); ++i)
    d->qpos[qadr("ramp" + std::to_string(i) + "rz")] = stage.ramps[i].yaw;
  // The original's lock, as it does it at run time: every joint of a locked box limited to [q, q].
  for (size_t i = 0; i < stage.boxes.size(); ++i) {
    if (!stage.boxes[i].locked) continue;
    for (const char* axis : {"tx", "ty", "tz", "rz"}) {
      const int j = mj_name2id(m, mjOBJ_JOINT, ("box" + std::to_string(i) + axis).c_str());
      m->jnt_limited[j] = 1;
      m->jnt_range[2 * j] = m->jnt_range[2 * j + 1] = d->qpos[m->jnt_qposadr[j]];
    }
  }
  mj_forward(m, d);

  auto pose = [&](const std::string& body) {
    const int b = mj_name2id(m, mjOBJ_BODY, body.c_str());
    return Pose{d->xpos[3 * b], d->xpos[3 * b + 1], d->xpos[3 * b + 2], d->qpos[qadr(body + "rz")]};
  };
  auto frame = [&] {
    Frame f;
    for (size_t i = 0; i < stage.agents.size(); ++i) f.agents.push_back(pose("agent" + std::to_string(i)));
    for (size_t i = 0; i < stage.boxes.size(); ++i) f.boxes.push_back(pose("box" + std::to_string(i)));
    for (size_t i = 0; i < stage.ramps.size(); ++i) f.ramps.push_back(pose("ramp" + std::to_string(i)));
    return f;
  };
  std::vector<Frame> frames;
  Frame now = frame();
  for (int k = 0; k < steps; ++k) {
    const std::vector<Move> moves = policy(k, now);
    // A weld holds while its agent's grab bit is set.
    for (size_t h = 0; h < stage.holds.size(); ++h) {
      const size_t a = size_t(stage.holds[h].agent);
      m->eq_active[h] = a < moves.size() && moves[a].grab ? 1 : 0;
    }
    for (size_t i = 0; i < stage.agents.size(); ++i) {
      const Move mv = i < moves.size() ? moves[i] : Move{};
      d->ctrl[3 * i] = ctrl(mv.x);
      d->ctrl[3 * i + 1] = ctrl(mv.y);
      d->ctrl[3 * i + 2] = ctrl(mv.turn);
    }
    for (int s = 0; s < kSubsteps; ++s) mj_step(m, d);
    now = frame();
    frames.push_back(now);
  }
  mj_deleteData(d);
  mj_deleteModel(m);
  return frames;
}

}  // namespace hns::parity
