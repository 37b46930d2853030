// Episode recording from a BatchSim (see recorder.hpp for why the batch runs one step longer than the game).
#include "replay/recorder.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "physics/scene.hpp"

namespace hns::replay {
namespace {

namespace phys = hns::physics;

constexpr uint64_t kActionStreamTag = 0xAC7105ULL << 32;  // keeps action streams apart from scene streams

// One env's episode being recorded.
struct EnvRecording {
  TrajectoryEpisode ep;
  bool active = false;  // false once the episode's last frame is in
  int last_frame = 0;
};

// Copies the state after `t` steps of env `env` into frame t. `step_actions` are the env's actions of step t
// (empty for frame 0, which gets the neutral action).
void capture(TrajectoryEpisode& ep, const batch::BatchSim& sim, int env, int t,
             std::span<const phys::AgentAction> step_actions) {
  const phys::World& world = sim.world(env);
  const batch::BatchState& s = sim.state();
  const int ma = sim.layout().max_agents, mb = sim.layout().max_boxes, mr = sim.layout().max_ramps;
  const int a_n = ep.num_agents(), b_n = ep.num_boxes, r_n = ep.num_ramps, o_n = ep.num_objects();
  const size_t f = size_t(t);

  auto pose = [](const phys::BodyState& st, float* out) {
    out[0] = float(st.pos[0]);
    out[1] = float(st.pos[1]);
    out[2] = float(st.pos[2]);
    out[3] = float(st.yaw());
  };
  for (int a = 0; a < a_n; ++a) pose(world.agent_state(a), &ep.agent_pose[(f * a_n + a) * 4]);
  for (int b = 0; b < b_n; ++b) pose(world.box_state(b), &ep.box_pose[(f * b_n + b) * 4]);
  for (int r = 0; r < r_n; ++r) pose(world.ramp_state(r), &ep.ramp_pose[(f * r_n + r) * 4]);

  // Locks (object o: boxes, then ramps) and grabs come from the world.
  for (int o = 0; o < o_n; ++o) {
    const bool locked = world.object_locked(o);
    const int team = world.object_lock_team(o);
    ep.object_lock[f * o_n + o] = !locked ? kUnlocked : team == 1 ? kLockedBySeekers : kLockedByHiders;
    ep.object_locker[f * o_n + o] = int8_t(world.object_locker(o));
  }
  for (int a = 0; a < a_n; ++a) ep.agent_holding[f * a_n + a] = int8_t(world.agent_holding(a));

  // Perception and rewards come from the batch state (slots padded to the batch maxima).
  const size_t ea = size_t(env) * ma;
  for (int i = 0; i < a_n; ++i) {
    for (int j = 0; j < a_n; ++j) {
      ep.vis_agents[(f * a_n + i) * a_n + j] = s.vis_agents[(ea + i) * ma + j];
    }
    for (int b = 0; b < b_n; ++b) ep.vis_boxes[(f * a_n + i) * b_n + b] = s.vis_boxes[(ea + i) * mb + b];
    for (int r = 0; r < r_n; ++r) ep.vis_ramps[(f * a_n + i) * r_n + r] = s.vis_ramps[(ea + i) * mr + r];
    for (int k = 0; k < kTrajectoryLidarRays; ++k) {
      const float d = s.lidar[(ea + i) * batch::Layout::kLidar + k];
      const double clamped = std::clamp(double(d), 0.0, 65535 * kLidarUnit);
      ep.lidar[(f * a_n + i) * kTrajectoryLidarRays + k] = uint16_t(std::lround(clamped / kLidarUnit));
    }
    ep.reward[f * a_n + i] = t == 0 ? 0.0f : s.reward[ea + i];
    const phys::AgentAction act = step_actions.empty() ? phys::AgentAction{} : step_actions[i];
    uint8_t* out = &ep.action[(f * a_n + i) * kActionFields];
    out[0] = act.move_x;
    out[1] = act.move_y;
    out[2] = act.turn;
    out[3] = act.grab;
    out[4] = act.lock;
  }
  ep.prep[f] = t <= ep.prep_steps ? 1 : 0;
  const int mf = sim.layout().max_food;
  for (int k = 0; k < ep.num_food; ++k) {
    const size_t i = size_t(env) * mf + k;
    float* out = &ep.food[(f * ep.num_food + k) * 4];
    std::copy_n(s.food_pos.data() + 3 * i, 3, out);
    out[3] = s.food_health[i];
  }
}

// The header of the env's current episode (its scene, the game's settings), blocks sized for `frames`.
void header(TrajectoryEpisode& ep, const batch::BatchSim& sim, int env, const batch::BatchConfig& config,
            const std::string& scene_name, uint64_t seed, int frames) {
  const phys::WorldConfig& game = config.world;
  const phys::World& world = sim.world(env);
  const phys::Scene& scene = world.scene();
  ep = TrajectoryEpisode{};
  ep.scene = scene_name;
  ep.layout = phys::layout_name(scene.layout);
  ep.seed = seed;
  ep.env = env;
  ep.episode = sim.state().episode[env];
  ep.horizon = game.horizon;
  ep.prep_steps = game.prep_steps();
  ep.step_time = game.physics.step_time;
  ep.num_hiders = scene.num_hiders;
  ep.num_seekers = scene.num_seekers;
  ep.num_boxes = int(scene.boxes.size());
  ep.num_elongated = scene.num_elongated;
  ep.num_ramps = int(scene.ramps.size());
  ep.num_food = int(scene.food.size());
  ep.outer_walls = scene.outer_walls;
  for (const phys::StaticBox& w : scene.wall_boxes) ep.walls.push_back({w.cx, w.cy, w.cz, w.hx, w.hy, w.hz});
  ep.cylinders.clear();
  if (scene.has_target)
    ep.cylinders.push_back({scene.target.x, scene.target.y, 0.5 * scene.target.sx, scene.target.sz});
  ep.sites.clear();
  for (const phys::Spawn& c : scene.sites) ep.sites.push_back({c.x, c.y, c.sx});
  for (const phys::Spawn& b : scene.boxes) ep.box_sizes.push_back({b.sx, b.sy, b.sz});
  const double* rect = config.rules.restrict_rect;
  std::copy(rect, rect + 4, ep.restrict_rect.begin());
  ep.resize(frames);
}

// Starts recording the env's current episode: header from its scene, frame 0 from the reset state.
void start(EnvRecording& rec, const batch::BatchSim& sim, int env, const RecordConfig& config) {
  header(rec.ep, sim, env, config.game, config.scene, config.game.seed, config.game.world.horizon + 1);
  capture(rec.ep, sim, env, 0, {});
  rec.active = true;
  rec.last_frame = 0;
}

// Summed mean team rewards over the episode, as the batch's episode statistics define them.
void finish(TrajectoryEpisode& ep) {
  const int a_n = ep.num_agents();
  ep.hider_return = ep.seeker_return = 0;
  for (int t = 0; t < ep.frames; ++t) {
    double hiders = 0, seekers = 0;
    for (int a = 0; a < a_n; ++a) (a < ep.num_hiders ? hiders : seekers) += ep.reward[size_t(t) * a_n + a];
    if (ep.num_hiders > 0) ep.hider_return += hiders / ep.num_hiders;
    if (ep.num_seekers > 0) ep.seeker_return += seekers / ep.num_seekers;
  }
}

}  // namespace

TrajectoryEpisode snapshot(const batch::BatchSim& sim, int env, const std::string& scene) {
  if (env < 0 || env >= sim.config().num_envs) {
    throw std::invalid_argument("env " + std::to_string(env) + ": the batch has envs 0 to " +
                                std::to_string(sim.config().num_envs - 1));
  }
  TrajectoryEpisode ep;
  header(ep, sim, env, sim.config(), scene, sim.config().seed, 1);
  capture(ep, sim, env, 0, {});
  // As in a recording, frame t (after t steps) lies in the preparation phase while t <= prep_steps.
  ep.prep[0] = sim.world(env).step_count() <= ep.prep_steps ? 1 : 0;
  for (int a = 0; a < ep.num_agents(); ++a)
    ep.reward[size_t(a)] = sim.state().reward[size_t(env) * sim.layout().max_agents + a];
  return ep;
}

void RandomActions::operator()(const batch::BatchSim& sim, std::span<phys::AgentAction> actions) {
  const int n_envs = sim.num_envs(), ma = sim.layout().max_agents;
  streams_.resize(size_t(n_envs));
  stream_episode_.resize(size_t(n_envs), -1);
  for (int e = 0; e < n_envs; ++e) {
    const int episode = sim.state().episode[e];
    if (stream_episode_[e] != episode) {
      streams_[e] = phys::Rng(seed_ ^ kActionStreamTag, uint64_t(e), uint64_t(episode));
      stream_episode_[e] = episode;
    }
    phys::Rng& rng = streams_[e];
    const int n = sim.world(e).num_agents();
    for (int a = 0; a < ma; ++a) {
      phys::AgentAction& act = actions[size_t(e) * ma + a];
      if (a >= n) {
        act = phys::AgentAction{};
        continue;
      }
      act.move_x = uint8_t(rng.uniform_int(0, phys::kMoveBins));
      act.move_y = uint8_t(rng.uniform_int(0, phys::kMoveBins));
      act.turn = uint8_t(rng.uniform_int(0, phys::kMoveBins));
      act.grab = uint8_t(rng.uniform_int(0, 2));
      act.lock = uint8_t(rng.uniform_int(0, 2));
    }
  }
}

batch::BatchConfig recording_batch_config(const batch::BatchConfig& game) {
  game.validate();
  batch::BatchConfig rec = game;
  const int prep = game.world.prep_steps();
  rec.world.horizon = game.world.horizon + 1;
  // ceil(fraction * horizon) must give the same preparation steps as the game.
  rec.world.prep_fraction = prep == 0 ? 0.0 : (prep - 0.5) / rec.world.horizon;
  rec.validate();
  if (rec.world.prep_steps() != prep) {
    throw std::logic_error("recording_batch_config: preparation steps changed from " + std::to_string(prep) +
                           " to " + std::to_string(rec.world.prep_steps()));
  }
  return rec;
}

RecordSummary record_episodes(const RecordConfig& config, const ActionFn& actions,
                              const std::function<void(const TrajectoryEpisode&)>& sink) {
  if (config.episodes < 1) {
    throw phys::ConfigError("episodes = " + std::to_string(config.episodes) + ": must be at least 1");
  }
  batch::BatchSim sim(recording_batch_config(config.game));
  const int n_envs = sim.num_envs(), ma = sim.layout().max_agents;
  const int horizon = config.game.world.horizon;
  std::vector<EnvRecording> recs(static_cast<size_t>(n_envs));
  for (int e = 0; e < n_envs; ++e) start(recs[e], sim, e, config);
  std::vector<phys::AgentAction> step_actions(size_t(n_envs) * ma);

  RecordSummary summary;
  const int max_discarded = 100 + 10 * config.episodes;
  while (summary.recorded < config.episodes) {
    actions(sim, step_actions);
    sim.step(step_actions);
    for (int e = 0; e < n_envs && summary.recorded < config.episodes; ++e) {
      EnvRecording& rec = recs[e];
      // A new episode number: the planned reset after a recorded episode, or numerical trouble cut it short.
      if (sim.state().episode[e] != rec.ep.episode) {
        if (rec.active && ++summary.discarded > max_discarded) {
          throw std::runtime_error(std::to_string(summary.discarded) +
                                   " episodes were cut short by numerical trouble; giving up");
        }
        start(rec, sim, e, config);
        continue;
      }
      if (!rec.active) continue;
      const int t = sim.world(e).step_count();
      if (t != rec.last_frame + 1) {
        throw std::logic_error("record_episodes: env " + std::to_string(e) + " went from step " +
                               std::to_string(rec.last_frame) + " to " + std::to_string(t));
      }
      capture(rec.ep, sim, e, t,
              std::span<const phys::AgentAction>(step_actions).subspan(size_t(e) * ma, ma));
      rec.last_frame = t;
      if (t == horizon) {
        finish(rec.ep);
        sink(rec.ep);
        ++summary.recorded;
        rec.active = false;
      }
    }
  }
  return summary;
}

}  // namespace hns::replay
