#include "batch/batch_sim.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace hns::batch {
namespace {

using Clock = std::chrono::steady_clock;
constexpr float kOutOfBoundsReward = -10.0f;  // docs/game.md §5.2
constexpr float kAgentRadius = float(physics::kAgentRadius);
constexpr float kArmRadius = float(physics::kArmRadius);
// Every arm lies within this distance of its agent's centre, with 1.8 mm to spare (far above rounding).
constexpr float kAgentReach = float(physics::kAgentReach);

// Most wall pieces a scene of this config can have (each interior wall splits in two at its door).
int max_walls(const physics::SceneConfig& scene) {
  switch (scene.layout) {
    case physics::Layout::kQuadrant:
      return 4 + 2 * 2;
    case physics::Layout::kRandomWalls:
      return 4 + 2 * std::max(0, scene.rooms.max - 1);
    case physics::Layout::kVarTri:
    case physics::Layout::kCounting:
      return 4 + 2;
    default:
      return 4;
  }
}

// The lidar fan (docs/game.md §4.2, §14.6): world-fixed horizontal directions 12° apart from +x, each 6 m
// long.
struct LidarFan {
  float dx[Layout::kLidar], dy[Layout::kLidar], dz[Layout::kLidar], length[Layout::kLidar];
  LidarFan() {
    for (int k = 0; k < Layout::kLidar; ++k) {
      const double angle = 2.0 * 3.14159265358979323846 * k / Layout::kLidar;
      dx[k] = float(std::cos(angle));
      dy[k] = float(std::sin(angle));
      dz[k] = 0.0f;
      length[k] = float(physics::kLidarRange);
    }
  }
};
const LidarFan kLidarFan;
const float kCosHalfCone = float(std::cos(physics::kVisionHalfAngle));
// Lines of sight one agent casts at most (other agents, boxes, ramps); the scene maxima keep far below it.
constexpr int kMaxSightLines = 128;

// prep_obs after t steps of an episode with `prep` preparation steps (docs/game.md §4.3): t / (prep + 1e-5),
// which first reads 1 after step prep + 1. Rounded to float that quotient would read 1 a step early once prep
// exceeds a few hundred, so it is capped just below 1 until then.
float prep_observation(int t, int prep) {
  if (t > prep) return 1.0f;
  return std::min(float(double(t) / (double(prep) + 1e-5)), std::nextafter(1.0f, 0.0f));
}

}  // namespace

// Per-env bookkeeping that is not part of the observable state.
struct BatchSim::EnvScratch {
  bool finished = false;  // an episode ended during the last step
  EpisodeStats stats;
  int64_t unstable_resets = 0;
  int64_t ns_physics = 0, ns_mirror = 0, ns_perception = 0, ns_observations = 0, ns_rewards = 0;
  std::vector<TraceEvent> trace;  // filled only while tracing
  physics::Rng food_rng;          // dynamic food's new spots, drawn from (seed, env, episode) per episode
};

void BatchConfig::validate() const {
  world.validate();
  world.scene.check_placeable();
  auto check = [](bool ok, const char* field, long long value, const char* allowed) {
    if (!ok) {
      std::ostringstream out;
      out << field << " = " << value << " is invalid: " << allowed;
      throw physics::ConfigError(out.str());
    }
  };
  check(num_envs >= 1 && num_envs <= (1 << 22), "envs", num_envs, "must be in [1, 4194304]");
  check(threads >= 1 && threads <= 4096, "threads", threads, "must be in [1, 4096]");
  check(envs_per_task >= 1, "envs_per_task", envs_per_task, "must be >= 1");
  check(first_env >= 0, "first_env", first_env, "must be >= 0");
}

void BatchState::allocate(const Layout& L, int num_envs) {
#define HNS_ALLOCATE_FIELD(type, name, count, doc) name.resize(size_t(num_envs) * size_t(count));
  HNS_BATCH_FIELDS(HNS_ALLOCATE_FIELD)
#undef HNS_ALLOCATE_FIELD
}

Layout Layout::of(const BatchConfig& config) {
  const physics::SceneConfig& scene = config.world.scene;
  Layout L;
  L.max_agents = config.world.agent_slots();
  L.max_boxes = scene.boxes.max;
  L.max_ramps = std::max(scene.ramps.max, config.world.obs_min_ramps);
  L.construction_sites = scene.sites.max;
  L.max_food = scene.food.max;  // SceneConfig::validate() allows sites or food, not both
  L.max_sites = std::max(L.construction_sites, L.max_food);
  L.site_features = L.max_food > 0             ? Layout::kFoodFeatures
                    : L.construction_sites > 0 ? Layout::kConstructionSiteFeatures
                                               : 0;
  L.max_walls = ::hns::batch::max_walls(scene);
  L.others = std::max(0, L.max_agents - 1);
  L.shape_boxes = L.max_walls + L.max_boxes;
  L.shape_wedges = L.max_ramps;
  L.shape_spheres = Layout::kSpheresPerAgent * L.max_agents;
  L.shape_cylinders = scene.target_diameter_max > 0 ? 1 : 0;
  return L;
}

size_t Layout::state_bytes_per_env() const {
  const Layout& L = *this;
  size_t bytes = 0;
#define HNS_FIELD_BYTES(type, name, count, doc) bytes += size_t(count) * sizeof(type);
  HNS_BATCH_FIELDS(HNS_FIELD_BYTES)
#undef HNS_FIELD_BYTES
  return bytes;
}

size_t BatchConfig::estimated_bytes() const {
  // One world: about 26 KB of ODE world, spaces, threading and scratch, 2.1 KB per body slot (ODE body,
  // geoms, auto-disable buffers, World bookkeeping) and 0.2 KB per wall: fitted to the resident memory of
  // 1000 and 4000 envs of both games (42 KB a quadrant world, 63 KB a full one).
  const Layout L = Layout::of(*this);
  const size_t bodies = size_t(L.max_agents + L.max_boxes + L.max_ramps);
  const size_t world = 26 * 1024 + bodies * 2150 + size_t(L.max_walls) * 200;
  return size_t(num_envs) * (L.state_bytes_per_env() + world);
}

BatchSim::BatchSim(const BatchConfig& config) : config_(config), epoch_(std::chrono::steady_clock::now()) {
  config_.validate();
  config_.world.compute_visibility = false;  // the batch's SIMD vision fills it
  layout_ = Layout::of(config_);
  if (layout_.others + layout_.max_boxes + layout_.max_ramps + layout_.max_food > kMaxSightLines) {
    throw std::logic_error(std::string(__FILE__) + ":" + std::to_string(__LINE__) + ": more than " +
                           std::to_string(kMaxSightLines) + " vision targets per agent");
  }
  state_.allocate(layout_, config_.num_envs);
  worlds_.reserve(config_.num_envs);
  for (int e = 0; e < config_.num_envs; ++e) {
    worlds_.push_back(std::make_unique<physics::World>(config_.world, config_.seed,
                                                       uint64_t(config_.first_env) + uint64_t(e)));
  }
  scratch_.resize(config_.num_envs);
  arena_ = std::make_unique<tbb::task_arena>(config_.threads);
  reset();
}

BatchSim::~BatchSim() = default;

void BatchSim::reset() {
  reset(std::span<const int32_t>());
}

void BatchSim::reseed(uint64_t seed) {
  config_.seed = seed;
  for (auto& w : worlds_) w->set_seed(seed);
}

void BatchSim::reset(std::span<const int32_t> episodes) {
  std::fill(final_mask_.begin(), final_mask_.end(), uint8_t(0));
  if (!episodes.empty() && int(episodes.size()) != config_.num_envs) {
    throw std::invalid_argument("BatchSim::reset: " + std::to_string(episodes.size()) +
                                " episode numbers for " + std::to_string(config_.num_envs) + " envs");
  }
  arena_->execute([&] {
    tbb::parallel_for(
        tbb::blocked_range<int>(0, config_.num_envs, config_.envs_per_task),
        [&](const tbb::blocked_range<int>& r) {
          for (int e = r.begin(); e != r.end(); ++e) {
            reset_env(e, episodes.empty() ? 0 : uint64_t(episodes[e]));
            observe_env(e);
            state_.done[e] = 0;
            std::fill_n(state_.reward.data() + size_t(e) * layout_.max_agents, layout_.max_agents, 0.0f);
          }
        },
        tbb::simple_partitioner());
  });
  finished_.clear();
}

void BatchSim::keep_final(std::span<const std::string> fields) {
  for (const std::string& name : fields) {
    bool found = false;
    state_.for_each_field([&](const char* field, std::span<const uint8_t> bytes) {
      if (name != field) return;
      found = true;
      const size_t env_bytes = bytes.size() / size_t(config_.num_envs);
      final_.push_back({name, bytes.data(), env_bytes, std::vector<uint8_t>(bytes.size(), 0)});
    });
    if (!found) throw std::invalid_argument("BatchSim::keep_final: no field " + name);
  }
  final_mask_.assign(size_t(config_.num_envs), 0);
}

const uint8_t* BatchSim::final_field(const std::string& name) const {
  for (const FinalField& f : final_)
    if (f.name == name) return f.copy.data();
  throw std::invalid_argument("BatchSim::final_field: " + name + " is not kept (keep_final)");
}

void BatchSim::step(std::span<const AgentAction> actions) {
  if (actions.size() != size_t(config_.num_envs) * layout_.max_agents) {
    throw std::invalid_argument(
        "BatchSim::step: got " + std::to_string(actions.size()) + " actions, expected " +
        std::to_string(size_t(config_.num_envs) * layout_.max_agents) + " (envs x max agents)");
  }
  std::fill(final_mask_.begin(), final_mask_.end(), uint8_t(0));
  arena_->execute([&] {
    tbb::parallel_for(
        tbb::blocked_range<int>(0, config_.num_envs, config_.envs_per_task),
        [&](const tbb::blocked_range<int>& r) { step_range(actions, r.begin(), r.end()); },
        tbb::simple_partitioner());
  });
  collect_finished();
}

void BatchSim::step_range(std::span<const AgentAction> actions, int begin, int end) {
  const int A = layout_.max_agents;
  const int thread = tracing_ ? std::max(0, tbb::this_task_arena::current_thread_index()) : 0;
  for (int e = begin; e < end; ++e) {
    EnvScratch& sc = scratch_[e];
    sc.finished = false;
    physics::World& world = *worlds_[e];
    // Adds the time since the last mark to a phase's counter (and, when tracing, records an event).
    Clock::time_point mark = Clock::now();
    auto phase_done = [&](const char* name, int64_t& counter) {
      const Clock::time_point now = Clock::now();
      counter += std::chrono::duration_cast<std::chrono::nanoseconds>(now - mark).count();
      if (tracing_) {
        sc.trace.push_back({name, std::chrono::duration_cast<std::chrono::nanoseconds>(mark - epoch_).count(),
                            std::chrono::duration_cast<std::chrono::nanoseconds>(now - epoch_).count(),
                            thread, e});
      }
      mark = now;
    };
    if (config_.world.task == physics::WorldConfig::Task::kCounting) {
      // Object counting: the agent's actions are ignored and the script sets every pose after the step.
      const AgentAction idle[1] = {};
      world.step(std::span<const AgentAction>(idle, size_t(world.num_agents())));
      pose_counting_env(e);
    } else {
      world.step(actions.subspan(size_t(e) * A, size_t(world.num_agents())));
    }
    phase_done("physics", sc.ns_physics);
    if (world.unstable()) {
      // Numerical trouble stays in this env: drop the episode, start a new one.
      ++sc.unstable_resets;
      std::fill_n(state_.reward.data() + size_t(e) * A, A, 0.0f);
      end_episode_env(e, true);
      phase_done("rewards+resets", sc.ns_rewards);
    } else {
      mirror_env(e);
      build_shapes(e);
      phase_done("mirror", sc.ns_mirror);
      vision_env(e);
      lidar_env(e);
      phase_done("vision+lidar", sc.ns_perception);
      rewards_env(e);
      if (state_.done[e] != 0) end_episode_env(e, false);
      phase_done("rewards+resets", sc.ns_rewards);
    }
    observe_env(e);
    phase_done("observations", sc.ns_observations);
  }
}

void BatchSim::set_tracing(bool on) {
  tracing_ = on;
}

std::vector<TraceEvent> BatchSim::take_trace() {
  std::vector<TraceEvent> all;
  for (EnvScratch& sc : scratch_) {
    all.insert(all.end(), sc.trace.begin(), sc.trace.end());
    sc.trace.clear();
  }
  return all;
}

void BatchSim::collect_finished() {
  finished_.clear();
  for (int e = 0; e < config_.num_envs; ++e) {
    EnvScratch& sc = scratch_[e];
    if (sc.finished) finished_.push_back(sc.stats);
    phase_times_.physics += sc.ns_physics * 1e-9;
    phase_times_.mirror += sc.ns_mirror * 1e-9;
    phase_times_.perception += sc.ns_perception * 1e-9;
    phase_times_.observations += sc.ns_observations * 1e-9;
    phase_times_.rewards += sc.ns_rewards * 1e-9;
    sc.ns_physics = sc.ns_mirror = sc.ns_perception = sc.ns_observations = sc.ns_rewards = 0;
  }
}

int64_t BatchSim::unstable_resets() const {
  int64_t n = 0;
  for (const EnvScratch& sc : scratch_) n += sc.unstable_resets;
  return n;
}

void BatchSim::load_scene(int env, const physics::Scene& scene) {
  if (scene.has_target && layout_.shape_cylinders == 0) {
    throw std::logic_error(
        "BatchSim::load_scene: a scene with a cylinder in a batch without a cylinder slot "
        "(its scene config has target_diameter_max 0)");
  }
  worlds_[env]->reset_with_scene(scene, uint64_t(state_.episode[env]));
  start_episode_env(env, uint64_t(state_.episode[env]));
  observe_env(env);
  state_.done[env] = 0;
  std::fill_n(state_.reward.data() + size_t(env) * layout_.max_agents, layout_.max_agents, 0.0f);
}

void BatchSim::reset_env(int env, uint64_t episode) {
  worlds_[env]->reset(episode);
  start_episode_env(env, episode);
}

void BatchSim::start_episode_env(int env, uint64_t episode) {
  const physics::Scene& scene = worlds_[env]->scene();
  if (int(scene.wall_boxes.size()) > layout_.max_walls) {
    throw std::logic_error("scene has " + std::to_string(scene.wall_boxes.size()) + " walls, layout allows " +
                           std::to_string(layout_.max_walls));
  }
  state_.episode[env] = int32_t(episode);
  state_.step_count[env] = 0;
  state_.num_walls[env] = int32_t(scene.wall_boxes.size());
  std::fill_n(state_.stat_prep.data() + size_t(env) * Layout::kPrepStats, Layout::kPrepStats, 0.0f);
  float* run = state_.stat_run.data() + size_t(env) * Layout::kRunStats;
  std::fill_n(run, Layout::kRunStats, 0.0f);
  run[kRampWallDist] = float(physics::kFloorSize);
  std::fill_n(state_.episode_return.data() + size_t(env) * 2, 2, 0.0f);
  // Walls never move: their shapes are written once per episode.
  const size_t sb = size_t(env) * layout_.shape_boxes;
  for (int w = 0; w < int(scene.wall_boxes.size()); ++w) {
    const physics::StaticBox& b = scene.wall_boxes[w];
    state_.shape_box_cx[sb + w] = float(b.cx);
    state_.shape_box_cy[sb + w] = float(b.cy);
    state_.shape_box_cz[sb + w] = float(b.cz);
    state_.shape_box_hx[sb + w] = float(b.hx);
    state_.shape_box_hy[sb + w] = float(b.hy);
    state_.shape_box_hz[sb + w] = float(b.hz);
    state_.shape_box_c[sb + w] = 1.0f;
    state_.shape_box_s[sb + w] = 0.0f;
  }
  const int nc = int(scene.sites.size()), nf = int(scene.food.size());
  if (nc > layout_.construction_sites || nf > layout_.max_food) {
    throw std::logic_error("scene has " + std::to_string(nc) + " construction sites and " +
                           std::to_string(nf) + " food items, layout allows " +
                           std::to_string(layout_.construction_sites) + " and " +
                           std::to_string(layout_.max_food));
  }
  for (int c = 0; c < layout_.construction_sites; ++c) {
    float* p = state_.site_pos.data() + (size_t(env) * layout_.construction_sites + c) * 3;
    p[0] = c < nc ? float(scene.sites[c].x) : 0.0f;
    p[1] = c < nc ? float(scene.sites[c].y) : 0.0f;
    p[2] = c < nc ? float(scene.sites[c].z) : 0.0f;
    state_.site_exists[size_t(env) * layout_.construction_sites + c] = c < nc ? 1 : 0;
  }
  for (int f = 0; f < layout_.max_food; ++f) {
    const size_t i = size_t(env) * layout_.max_food + f;
    float* p = state_.food_pos.data() + i * 3;
    p[0] = f < nf ? float(scene.food[f].x) : 0.0f;
    p[1] = f < nf ? float(scene.food[f].y) : 0.0f;
    p[2] = f < nf ? float(scene.food[f].z) : 0.0f;
    state_.food_health[i] = f < nf ? float(config_.world.food.max_health) : 0.0f;
    state_.food_respawn[i] = 0;
    state_.food_exists[i] = f < nf ? 1 : 0;
  }
  std::fill_n(state_.food_eaten.data() + size_t(env) * layout_.max_agents, layout_.max_agents, 0.0f);
  scratch_[env].food_rng =
      physics::Rng(config_.seed ^ 0xF00DF00DULL, uint64_t(config_.first_env) + uint64_t(env), episode);
  state_.task_complete[env] = 0;
  if (config_.world.task == physics::WorldConfig::Task::kCounting) pose_counting_env(env);
  if (layout_.shape_cylinders > 0) {
    const physics::Spawn& t = scene.target;
    state_.shape_cyl_cx[env] = scene.has_target ? float(t.x) : 0.0f;
    state_.shape_cyl_cy[env] = scene.has_target ? float(t.y) : 0.0f;
    state_.shape_cyl_r[env] = scene.has_target ? float(0.5 * t.sx) : 0.0f;
    state_.shape_cyl_h[env] = scene.has_target ? float(t.sz) : 0.0f;
  }
  refresh_env(env);
  std::copy_n(state_.box_pos.data() + size_t(env) * layout_.max_boxes * 3, layout_.max_boxes * 3,
              state_.box_pos_start.data() + size_t(env) * layout_.max_boxes * 3);
  std::copy_n(state_.ramp_pos.data() + size_t(env) * layout_.max_ramps * 3, layout_.max_ramps * 3,
              state_.ramp_pos_start.data() + size_t(env) * layout_.max_ramps * 3);
  std::copy_n(state_.agent_pos.data() + size_t(env) * layout_.max_agents * 3, layout_.max_agents * 3,
              state_.agent_pos_start.data() + size_t(env) * layout_.max_agents * 3);
  std::copy_n(state_.box_locked.data() + size_t(env) * layout_.max_boxes, layout_.max_boxes,
              state_.task_locked.data() + size_t(env) * layout_.max_boxes);
  if (config_.world.is_lock_task()) {
    const float* agent = state_.agent_pos.data() + size_t(env) * layout_.max_agents * 3;
    state_.task_spawn[size_t(env) * 2] = agent[0];
    state_.task_spawn[size_t(env) * 2 + 1] = agent[1];
    lockbox_retarget(env);
  }
}

void BatchSim::resync(int env) {
  refresh_env(env);
  observe_env(env);
}

void BatchSim::refresh_env(int env) {
  mirror_env(env);
  build_shapes(env);
  vision_env(env);
  lidar_env(env);
}

namespace {
// Copies the first `active` of `slots` bodies (get(i) -> BodyState) into SoA fields; later slots are zeroed.
template <class Get>
void mirror_bodies(int slots, int active, Get&& get, float* pos, float* rot, float* vel, float* angvel) {
  for (int i = 0; i < slots; ++i) {
    const physics::BodyState b = i < active ? get(i) : physics::BodyState{};
    for (int k = 0; k < 3; ++k) {
      pos[3 * i + k] = float(b.pos[k]);
      vel[3 * i + k] = float(b.vel[k]);
    }
    rot[2 * i] = float(b.cos_yaw);
    rot[2 * i + 1] = float(b.sin_yaw);
    angvel[i] = float(b.ang_vel);
  }
}
}  // namespace

void BatchSim::mirror_env(int env) {
  const physics::World& world = *worlds_[env];
  const Layout& L = layout_;
  BatchState& s = state_;
  const size_t a0 = size_t(env) * L.max_agents, b0 = size_t(env) * L.max_boxes,
               r0 = size_t(env) * L.max_ramps;
  mirror_bodies(
      L.max_agents, world.num_agents(), [&](int i) { return world.agent_state(i); },
      s.agent_pos.data() + (3 * a0), s.agent_rot.data() + (2 * a0), s.agent_vel.data() + (3 * a0),
      s.agent_angvel.data() + a0);
  mirror_bodies(
      L.max_boxes, world.num_boxes(), [&](int i) { return world.box_state(i); }, s.box_pos.data() + (3 * b0),
      s.box_rot.data() + (2 * b0), s.box_vel.data() + (3 * b0), s.box_angvel.data() + b0);
  mirror_bodies(
      L.max_ramps, world.num_ramps(), [&](int i) { return world.ramp_state(i); },
      s.ramp_pos.data() + (3 * r0), s.ramp_rot.data() + (2 * r0), s.ramp_vel.data() + (3 * r0),
      s.ramp_angvel.data() + r0);
  for (int a = 0; a < L.max_agents; ++a) {
    const bool exists = a < world.num_agents();
    s.agent_exists[a0 + a] = exists ? 1 : 0;
    s.agent_hider[a0 + a] = exists && world.team(a) == physics::Team::kHider ? 1 : 0;
  }
  const physics::Scene& scene = world.scene();
  for (int b = 0; b < L.max_boxes; ++b) {
    const bool exists = b < world.num_boxes();
    s.box_exists[b0 + b] = exists ? 1 : 0;
    s.box_locked[b0 + b] = exists && world.object_locked(b) ? 1 : 0;
    s.box_locker[b0 + b] = int8_t(exists ? world.object_locker(b) : -1);
    s.box_size[3 * (b0 + b) + 0] = exists ? float(scene.boxes[b].sx) : 0.0f;
    s.box_size[3 * (b0 + b) + 1] = exists ? float(scene.boxes[b].sy) : 0.0f;
    s.box_size[3 * (b0 + b) + 2] = exists ? float(scene.boxes[b].sz) : 0.0f;
  }
  for (int r = 0; r < L.max_ramps; ++r) {
    const bool exists = r < world.num_ramps();
    const int object = world.num_boxes() + r;
    s.ramp_exists[r0 + r] = exists ? 1 : 0;
    s.ramp_locked[r0 + r] = exists && world.object_locked(object) ? 1 : 0;
    s.ramp_locker[r0 + r] = int8_t(exists ? world.object_locker(object) : -1);
  }
}

void BatchSim::build_shapes(int env) {
  const Layout& L = layout_;
  BatchState& s = state_;
  const int walls = s.num_walls[env];
  const size_t sb = size_t(env) * L.shape_boxes;
  for (int k = walls; k < L.shape_boxes; ++k) {
    const int b = k - walls;
    const size_t i = size_t(env) * L.max_boxes + b;
    const bool exists = b < L.max_boxes && s.box_exists[i] != 0;
    s.shape_box_cx[sb + k] = exists ? s.box_pos[3 * i] : 0.0f;
    s.shape_box_cy[sb + k] = exists ? s.box_pos[3 * i + 1] : 0.0f;
    s.shape_box_cz[sb + k] = exists ? s.box_pos[3 * i + 2] : kParkedZ;
    s.shape_box_hx[sb + k] = exists ? 0.5f * s.box_size[3 * i] : 0.01f;
    s.shape_box_hy[sb + k] = exists ? 0.5f * s.box_size[3 * i + 1] : 0.01f;
    s.shape_box_hz[sb + k] = exists ? 0.5f * s.box_size[3 * i + 2] : 0.01f;
    s.shape_box_c[sb + k] = exists ? s.box_rot[2 * i] : 1.0f;
    s.shape_box_s[sb + k] = exists ? s.box_rot[2 * i + 1] : 0.0f;
  }
  const size_t sw = size_t(env) * L.shape_wedges;
  for (int k = 0; k < L.shape_wedges; ++k) {
    const size_t i = size_t(env) * L.max_ramps + k;
    const bool exists = k < L.max_ramps && s.ramp_exists[i] != 0;
    s.shape_wedge_cx[sw + k] = exists ? s.ramp_pos[3 * i] : 0.0f;
    s.shape_wedge_cy[sw + k] = exists ? s.ramp_pos[3 * i + 1] : 0.0f;
    s.shape_wedge_cz[sw + k] = exists ? s.ramp_pos[3 * i + 2] : kParkedZ;
    s.shape_wedge_c[sw + k] = exists ? s.ramp_rot[2 * i] : 1.0f;
    s.shape_wedge_s[sw + k] = exists ? s.ramp_rot[2 * i + 1] : 0.0f;
  }
  // Per agent: its body sphere, then its two arms (docs/game.md §1.2), placed by the agent's yaw.
  const size_t ss = size_t(env) * L.shape_spheres;
  for (int a = 0; a < L.max_agents; ++a) {
    const size_t i = size_t(env) * L.max_agents + a;
    const bool exists = s.agent_exists[i] != 0;
    float arms[2][3];
    physics::arm_centres(s.agent_pos.data() + (3 * i), s.agent_rot[2 * i], s.agent_rot[2 * i + 1], arms);
    const float* centres[Layout::kSpheresPerAgent] = {s.agent_pos.data() + (3 * i), arms[0], arms[1]};
    for (int k = 0; k < Layout::kSpheresPerAgent; ++k) {
      const size_t slot = ss + size_t(a) * Layout::kSpheresPerAgent + k;
      s.shape_sphere_cx[slot] = exists ? centres[k][0] : 0.0f;
      s.shape_sphere_cy[slot] = exists ? centres[k][1] : 0.0f;
      s.shape_sphere_cz[slot] = exists ? centres[k][2] : kParkedZ;
      s.shape_sphere_r[slot] = !exists ? 0.01f : k == 0 ? kAgentRadius : kArmRadius;
    }
  }
}

namespace {
// Cone test (docs/game.md §4.1): the target lies within 67.5° of the viewer's facing direction (−y at yaw 0).
bool in_cone(const float* viewer_pos, const float* viewer_rot, const float* target_pos) {
  const float dx = target_pos[0] - viewer_pos[0], dy = target_pos[1] - viewer_pos[1];
  const float fx = viewer_rot[1], fy = -viewer_rot[0];
  const float len = std::sqrt(dx * dx + dy * dy);
  return len == 0.0f || dx * fx + dy * fy >= kCosHalfCone * len;
}
}  // namespace

ShapesView BatchSim::shapes(int env) const {
  const BatchState& s = state_;
  const physics::World& world = *worlds_[env];
  const size_t b = size_t(env) * layout_.shape_boxes, w = size_t(env) * layout_.shape_wedges;
  const size_t p = size_t(env) * layout_.shape_spheres;
  ShapesView v;
  v.box_cx = s.shape_box_cx.data() + b, v.box_cy = s.shape_box_cy.data() + b;
  v.box_cz = s.shape_box_cz.data() + b, v.box_hx = s.shape_box_hx.data() + b;
  v.box_hy = s.shape_box_hy.data() + b, v.box_hz = s.shape_box_hz.data() + b;
  v.box_c = s.shape_box_c.data() + b, v.box_s = s.shape_box_s.data() + b;
  v.num_boxes = layout_.shape_boxes, v.live_boxes = s.num_walls[env] + world.num_boxes();
  v.wedge_cx = s.shape_wedge_cx.data() + w, v.wedge_cy = s.shape_wedge_cy.data() + w;
  v.wedge_cz = s.shape_wedge_cz.data() + w, v.wedge_c = s.shape_wedge_c.data() + w;
  v.wedge_s = s.shape_wedge_s.data() + w;
  v.num_wedges = layout_.shape_wedges, v.live_wedges = world.num_ramps();
  v.sphere_cx = s.shape_sphere_cx.data() + p, v.sphere_cy = s.shape_sphere_cy.data() + p;
  v.sphere_cz = s.shape_sphere_cz.data() + p, v.sphere_r = s.shape_sphere_r.data() + p;
  v.num_spheres = layout_.shape_spheres;
  v.live_spheres = Layout::kSpheresPerAgent * world.num_agents();
  v.spheres_per_body = Layout::kSpheresPerAgent;
  v.body_reach = kAgentReach;
  const size_t c = size_t(env) * layout_.shape_cylinders;
  v.cyl_cx = s.shape_cyl_cx.data() + c, v.cyl_cy = s.shape_cyl_cy.data() + c;
  v.cyl_r = s.shape_cyl_r.data() + c, v.cyl_h = s.shape_cyl_h.data() + c;
  v.num_cylinders = layout_.shape_cylinders;
  v.live_cylinders = world.scene().has_target ? 1 : 0;
  return v;
}

// Vision (docs/game.md §4.1): a target is seen when its sight point lies in the viewer's cone and the first
// shape on the segment from the viewer's centre to that point is the target itself (an agent's arms count as
// the agent). Sight points are centres, a ramp's its centroid (physics::ramp_sight_point): all lie inside
// their solid, so the segment always enters the target well before its end. Each viewer's lines of sight to
// the targets in its cone form one ray fan.
void BatchSim::vision_env(int env) {
  const Layout& L = layout_;
  BatchState& s = state_;
  const ShapesView shapes = this->shapes(env);
  const int walls = s.num_walls[env];
  const float* agent_pos = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
  const float* agent_rot = s.agent_rot.data() + size_t(env) * L.max_agents * 2;
  const uint8_t* agent_exists = s.agent_exists.data() + size_t(env) * L.max_agents;
  const float* box_pos = s.box_pos.data() + size_t(env) * L.max_boxes * 3;
  const uint8_t* box_exists = s.box_exists.data() + size_t(env) * L.max_boxes;
  const float* ramp_pos = s.ramp_pos.data() + size_t(env) * L.max_ramps * 3;
  const float* ramp_rot = s.ramp_rot.data() + size_t(env) * L.max_ramps * 2;
  const uint8_t* ramp_exists = s.ramp_exists.data() + size_t(env) * L.max_ramps;
  uint8_t* vis_agents = s.vis_agents.data() + size_t(env) * L.max_agents * L.max_agents;
  uint8_t* vis_boxes = s.vis_boxes.data() + size_t(env) * L.max_agents * L.max_boxes;
  uint8_t* vis_ramps = s.vis_ramps.data() + size_t(env) * L.max_agents * L.max_ramps;
  const float* food_pos = s.food_pos.data() + size_t(env) * L.max_food * 3;
  const uint8_t* food_exists = s.food_exists.data() + size_t(env) * L.max_food;
  uint8_t* vis_food = s.vis_food.data() + size_t(env) * L.max_agents * L.max_food;
  std::fill_n(vis_agents, L.max_agents * L.max_agents, 0);
  std::fill_n(vis_boxes, L.max_agents * L.max_boxes, 0);
  std::fill_n(vis_ramps, L.max_agents * L.max_ramps, 0);
  std::fill_n(vis_food, L.max_agents * L.max_food, 0);

  // One viewer's lines of sight: unit direction and length per target in the cone, the shape id that must
  // be hit first, and the visibility flag to set.
  float dx[kMaxSightLines], dy[kMaxSightLines], dz[kMaxSightLines], len[kMaxSightLines], t[kMaxSightLines];
  int32_t want[kMaxSightLines], hit[kMaxSightLines];
  uint8_t* flag[kMaxSightLines];
  for (int a = 0; a < L.max_agents; ++a) {
    if (agent_exists[a] == 0) continue;
    const float* o = agent_pos + 3 * a;
    int n = 0;
    auto aim = [&](const float* target, int target_id, uint8_t* out) {
      if (!in_cone(o, agent_rot + 2 * a, target)) return;
      const float ex = target[0] - o[0], ey = target[1] - o[1], ez = target[2] - o[2];
      const float d = std::sqrt(ex * ex + ey * ey + ez * ez);
      if (d < 1e-6f) {
        *out = 1;  // the same centre: nothing can be in between
        return;
      }
      dx[n] = ex / d, dy[n] = ey / d, dz[n] = ez / d, len[n] = d;
      want[n] = target_id, flag[n] = out;
      ++n;
    };
    vis_agents[a * L.max_agents + a] = 1;
    for (int j = 0; j < L.max_agents; ++j) {
      if (j != a && agent_exists[j] != 0)
        aim(agent_pos + 3 * j, shapes.sphere_id(j), &vis_agents[a * L.max_agents + j]);
    }
    for (int b = 0; b < L.max_boxes; ++b) {
      if (box_exists[b] != 0) aim(box_pos + 3 * b, walls + b, &vis_boxes[a * L.max_boxes + b]);
    }
    for (int r = 0; r < L.max_ramps; ++r) {
      if (ramp_exists[r] == 0) continue;
      const float* p = ramp_pos + 3 * r;
      float centroid[3];
      physics::ramp_sight_point(p[0], p[1], p[2], ramp_rot[2 * r], ramp_rot[2 * r + 1], centroid);
      aim(centroid, shapes.wedge_id(r), &vis_ramps[a * L.max_ramps + r]);
    }
    // A food item is a point, not a shape: seen when nothing lies on the segment to it (docs/game.md §4.1's
    // rule for site targets), so the shape that must be hit first is none (-1).
    for (int f = 0; f < L.max_food; ++f) {
      if (food_exists[f] != 0) aim(food_pos + 3 * f, -1, &vis_food[a * L.max_food + f]);
    }
    first_hits(shapes, RayFan{o[0], o[1], o[2], dx, dy, dz, len, n, shapes.sphere_id(a)}, t, hit);
    for (int k = 0; k < n; ++k) *flag[k] = hit[k] == want[k] ? 1 : 0;
  }
  // The world's grab and lock use this step's object visibility in the next step.
  physics::World& world = *worlds_[env];
  std::span<uint8_t> object_vis = world.object_visibility();
  const int n_obj = world.num_objects();
  for (int a = 0; a < world.num_agents(); ++a) {
    for (int b = 0; b < world.num_boxes(); ++b) object_vis[a * n_obj + b] = vis_boxes[a * L.max_boxes + b];
    for (int r = 0; r < world.num_ramps(); ++r) {
      object_vis[a * n_obj + world.num_boxes() + r] = vis_ramps[a * L.max_ramps + r];
    }
  }
}

// Lidar (docs/game.md §4.2, §14.6): per agent one fan of 30 world-fixed horizontal rays, the first hit within
// 6 m, else 6. Empty agent slots read 0.
void BatchSim::lidar_env(int env) {
  const Layout& L = layout_;
  BatchState& s = state_;
  const ShapesView shapes = this->shapes(env);
  const float* agent_pos = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
  const uint8_t* agent_exists = s.agent_exists.data() + size_t(env) * L.max_agents;
  float* lidar = s.lidar.data() + size_t(env) * L.max_agents * Layout::kLidar;
  int32_t hit[Layout::kLidar];
  for (int a = 0; a < L.max_agents; ++a) {
    float* out = lidar + a * Layout::kLidar;
    if (agent_exists[a] == 0) {
      std::fill_n(out, Layout::kLidar, 0.0f);
      continue;
    }
    const float* o = agent_pos + 3 * a;
    first_hits(shapes,
               RayFan{o[0], o[1], o[2], kLidarFan.dx, kLidarFan.dy, kLidarFan.dz, kLidarFan.length,
                      Layout::kLidar, shapes.sphere_id(a)},
               out, hit);
    for (int k = 0; k < Layout::kLidar; ++k) {
      if (hit[k] < 0) out[k] = float(physics::kLidarRange);
    }
  }
}

void BatchSim::rewards_env(int env) {
  const Layout& L = layout_;
  BatchState& s = state_;
  const physics::WorldConfig& wc = config_.world;
  const physics::World& world = *worlds_[env];
  const int t = world.step_count();
  s.step_count[env] = t;
  const int n = world.num_agents();
  const float* pos = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
  const uint8_t* hider = s.agent_hider.data() + size_t(env) * L.max_agents;
  const uint8_t* vis = s.vis_agents.data() + size_t(env) * L.max_agents * L.max_agents;
  const double* rect = wc.restrict_rect;
  auto outside = [rect](const float* p) {
    return p[0] < rect[0] || p[0] > rect[2] || p[1] < rect[1] || p[1] > rect[3];
  };

  // Joint zero-sum (docs/game.md §5.1): every hider gets -1 if any hider is seen by any seeker, else +1;
  // seekers the opposite. Out of bounds replaces an agent's reward with -10; in the quadrant game any box or
  // ramp out of bounds costs everyone -10 (§5.2). Everything is 0 during the preparation phase.
  bool any_seen = false;
  for (int sk = 0; sk < n; ++sk) {
    if (hider[sk] != 0) continue;
    for (int h = 0; h < n; ++h) any_seen = any_seen || (hider[h] != 0 && vis[sk * L.max_agents + h] != 0);
  }
  bool objects_out = false;
  if (wc.penalize_objects_out) {
    for (int b = 0; b < world.num_boxes(); ++b)
      objects_out = objects_out || outside(s.box_pos.data() + ((size_t(env) * L.max_boxes + b) * 3));
    for (int r = 0; r < world.num_ramps(); ++r)
      objects_out = objects_out || outside(s.ramp_pos.data() + ((size_t(env) * L.max_ramps + r) * 3));
  }
  const bool prep = t <= wc.prep_steps();
  float* reward = s.reward.data() + size_t(env) * L.max_agents;
  if (wc.is_transfer_task()) {
    // A completed blueprint absorbs the rest of its episode: reward 0, whatever happens (the trainer leaves
    // those steps out).
    const bool absorbed = s.task_complete[env] != 0;
    if (absorbed) {
      std::fill_n(reward, L.max_agents, 0.0f);
    } else if (wc.is_lock_task()) {
      lockbox_rewards_env(env, reward);
    } else if (wc.task == physics::WorldConfig::Task::kBlueprint) {
      blueprint_rewards_env(env, reward);
    } else if (wc.task == physics::WorldConfig::Task::kCounting) {
      std::fill_n(reward, L.max_agents, 0.0f);  // a supervised probe: no reward
    } else {
      shelter_rewards_env(env, reward);
    }
    for (int a = 0; a < L.max_agents; ++a) {
      if (!absorbed && a < n && outside(pos + 3 * a)) reward[a] = kOutOfBoundsReward;
      if (a >= n) reward[a] = 0.0f;
    }
    s.episode_return[size_t(env) * 2] += reward[0];
    s.done[env] = world.done() ? 1 : 0;
    return;
  }
  for (int a = 0; a < L.max_agents; ++a) {
    float r = 0.0f;
    if (a < n && !prep) {
      r = (hider[a] != 0) == any_seen ? -1.0f : 1.0f;
      if (objects_out || outside(pos + 3 * a)) r = kOutOfBoundsReward;
    }
    reward[a] = r;
  }
  if (L.max_food > 0) food_env(env, reward, prep);  // added to the game's (its wrapper is outermost)
  float hider_sum = 0, seeker_sum = 0;
  int hiders = 0;
  for (int a = 0; a < n; ++a) {
    (hider[a] != 0 ? hider_sum : seeker_sum) += reward[a];
    hiders += hider[a];
  }
  float* ret = s.episode_return.data() + size_t(env) * 2;
  if (hiders > 0) ret[0] += hider_sum / hiders;
  if (n - hiders > 0) ret[1] += seeker_sum / (n - hiders);
  if (!prep) track_env(env, any_seen);

  // Statistics at the end of the preparation phase (docs/game.md §7): when prep_obs first reads 1, after step
  // prep_steps + 1 (or at the last step of an episode too short for that).
  if (t == std::min(wc.prep_steps() + 1, wc.horizon)) {
    measure_env(env, s.stat_prep.data() + size_t(env) * Layout::kPrepStats);
  }
  s.done[env] = world.done() ? 1 : 0;
}

// The shelter reward's rays (docs/game.md §9.3): 100 start points evenly spaced around the square
// [0.202, 5.798]² on the floor, 25 per side, each side's from its first corner (counter-clockwise from
// (0.202, 0.202)) up to but not including the next, aimed at the cylinder's centre. A ray reaches the
// cylinder when nothing else lies on the segment from its start to the cylinder; the segments are cast the
// other way, as one fan from the centre that skips the cylinder (nothing else can be inside it), so the 100
// rays share the vector kernel's blocks.
namespace {
constexpr int kShelterRaysPerSide = 25;
constexpr int kShelterRays = 4 * kShelterRaysPerSide;
constexpr float kShelterEdgeLo = 0.202f, kShelterEdgeHi = 5.798f;  // m
constexpr float kShelterRayCost = 0.001f;                          // reward per ray that reaches the cylinder
}  // namespace

int BatchSim::shelter_rays_reaching(int env) const {
  const physics::Scene& scene = worlds_[env]->scene();
  if (!scene.has_target) return 0;
  const ShapesView shapes = this->shapes(env);
  const float cx = float(scene.target.x), cy = float(scene.target.y), cz = float(scene.target.z);
  alignas(64) float dx[kShelterRays], dy[kShelterRays], dz[kShelterRays], len[kShelterRays], t[kShelterRays];
  alignas(64) int32_t id[kShelterRays];
  for (int side = 0; side < 4; ++side) {
    for (int k = 0; k < kShelterRaysPerSide; ++k) {
      const int i = side * kShelterRaysPerSide + k;
      const float step = (kShelterEdgeHi - kShelterEdgeLo) * float(k) / kShelterRaysPerSide;
      const float up = kShelterEdgeLo + step, down = kShelterEdgeHi - step;
      const float ox = side == 0 ? up : side == 1 ? kShelterEdgeHi : side == 2 ? down : kShelterEdgeLo;
      const float oy = side == 0 ? kShelterEdgeLo : side == 1 ? up : side == 2 ? kShelterEdgeHi : down;
      const float ex = ox - cx, ey = oy - cy, ez = 0.0f - cz;
      len[i] = std::sqrt(ex * ex + ey * ey + ez * ez);
      dx[i] = ex / len[i], dy[i] = ey / len[i], dz[i] = ez / len[i];
    }
  }
  first_hits(shapes, RayFan{cx, cy, cz, dx, dy, dz, len, kShelterRays, shapes.cylinder_id(0)}, t, id);
  int reaching = 0;
  for (int i = 0; i < kShelterRays; ++i) reaching += id[i] < 0;
  return reaching;
}

void BatchSim::shelter_rewards_env(int env, float* reward) {
  std::fill_n(reward, layout_.max_agents, -kShelterRayCost * float(shelter_rays_reaching(env)));
}

// Blueprint construction (docs/game.md §9.1). Box corners are the middles of a box's vertical edges, (±sx/2,
// ±sy/2, 0) from its centre turned by its yaw (tilt is ignored: the batch mirrors yaw only); a site's corners
// are (±0.25, ±0.25, 0) from its centre. Dense: for each site corner, the smooth minimum over every box
// corner of the distance, sum d e^(αd) / sum e^(αd) with α = -1.5; the reward is -0.05 x their mean.
// Completion: every site has a box centre within 0.1 m of its centre and every site corner a box corner
// within 0.1 m; it pays 3 per site (on top of that step's dense reward) and sets task_complete.
constexpr double kBlueprintAlpha = -1.5;
constexpr double kBlueprintDenseScale = 0.05;
constexpr double kBlueprintRadius = 0.1;      // m
constexpr double kBlueprintSiteReward = 3.0;  // per site, on completion

void BatchSim::blueprint_rewards_env(int env, float* reward) {
  const Layout& L = layout_;
  BatchState& s = state_;
  const int nb = worlds_[env]->num_boxes();
  const size_t eb = size_t(env) * L.max_boxes, ec = size_t(env) * L.construction_sites;
  constexpr double kSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
  auto box_corner = [&](int b, int k, double* out) {
    const float* p = s.box_pos.data() + (eb + b) * 3;
    const float* r = s.box_rot.data() + (eb + b) * 2;
    const float* sz = s.box_size.data() + (eb + b) * 3;
    const double lx = kSigns[k][0] * 0.5 * sz[0], ly = kSigns[k][1] * 0.5 * sz[1];
    out[0] = p[0] + r[0] * lx - r[1] * ly;
    out[1] = p[1] + r[1] * lx + r[0] * ly;
    out[2] = p[2];
  };
  auto dist = [](const double* a, const double* b) {
    return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                     (a[2] - b[2]) * (a[2] - b[2]));
  };
  double smooth_sum = 0.0;
  int site_corners = 0, sites = 0;
  bool complete = nb > 0;
  for (int c = 0; c < L.construction_sites; ++c) {
    if (s.site_exists[ec + c] == 0) continue;
    ++sites;
    const float* sp = s.site_pos.data() + (ec + c) * 3;
    const double centre[3] = {sp[0], sp[1], sp[2]};
    double nearest_centre = std::numeric_limits<double>::infinity();
    for (int b = 0; b < nb; ++b) {
      const float* p = s.box_pos.data() + (eb + b) * 3;
      const double box[3] = {p[0], p[1], p[2]};
      nearest_centre = std::min(nearest_centre, dist(centre, box));
    }
    complete = complete && nearest_centre < kBlueprintRadius;
    for (int k = 0; k < 4; ++k) {
      const double corner[3] = {centre[0] + kSigns[k][0] * 0.5 * physics::kSiteSize,
                                centre[1] + kSigns[k][1] * 0.5 * physics::kSiteSize, centre[2]};
      double num = 0.0, den = 0.0, nearest = std::numeric_limits<double>::infinity();
      for (int b = 0; b < nb; ++b) {
        for (int q = 0; q < 4; ++q) {
          double bc[3];
          box_corner(b, q, bc);
          const double d = dist(corner, bc), w = std::exp(kBlueprintAlpha * d);
          num += d * w;
          den += w;
          nearest = std::min(nearest, d);
        }
      }
      smooth_sum += den > 0.0 ? num / den : 0.0;
      ++site_corners;
      complete = complete && nearest < kBlueprintRadius;
    }
  }
  double r = site_corners > 0 ? -kBlueprintDenseScale * smooth_sum / site_corners : 0.0;
  if (complete && sites > 0) {
    r += kBlueprintSiteReward * sites;
    s.task_complete[env] = 1;
  }
  std::fill_n(reward, L.max_agents, float(r));
}

// Object counting: the agent pinned at its spot facing +y (yaw pi: an agent faces (sin yaw, -cos yaw)), box k
// where the script has it after this many steps (docs/transfer.md "Object counting").
void BatchSim::pose_counting_env(int env) {
  physics::World& world = *worlds_[env];
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

// The food variants (docs/game.md §5.4), after the step: every hider the previous observation let eat an item
// (food_eat_ok) and within eat_radius of it eats 1 unit of it, outside the preparation phase; hiders that
// would together eat more than is left share it. An item eaten up stays at 0 for respawn_steps steps (the
// step it was emptied counts as the first), then its health resets, at a new spot with relocate. Each hider
// gets the units it ate, or the hiders' mean of them (joint_mean), times reward_scale; seekers get nothing.
void BatchSim::food_env(int env, float* reward, bool prep) {
  const Layout& L = layout_;
  BatchState& s = state_;
  const physics::FoodConfig& fc = config_.world.food;
  const int n = worlds_[env]->num_agents(), F = L.max_food;
  const size_t ea = size_t(env) * L.max_agents, ef = size_t(env) * F;
  const float* pos = s.agent_pos.data() + ea * 3;
  const uint8_t* hider = s.agent_hider.data() + ea;
  const uint8_t* eat_ok = s.food_eat_ok.data() + ea * F;
  float* eaten = s.food_eaten.data() + ea;
  std::fill_n(eaten, L.max_agents, 0.0f);
  const float reach2 = float(fc.eat_radius * fc.eat_radius);
  float total = 0.0f;
  for (int f = 0; f < F; ++f) {
    const size_t i = ef + size_t(f);
    if (s.food_exists[i] == 0) continue;
    float* p = s.food_pos.data() + i * 3;
    float& health = s.food_health[i];
    auto eats = [&](int a) {
      if (prep || health <= 0.0f || eat_ok[a * F + f] == 0) return false;
      const float dx = pos[3 * a] - p[0], dy = pos[3 * a + 1] - p[1], dz = pos[3 * a + 2] - p[2];
      return dx * dx + dy * dy + dz * dz < reach2;
    };
    int count = 0;
    for (int a = 0; a < n; ++a) count += eats(a) ? 1 : 0;
    if (count > 0) {
      const float share = std::min(1.0f, health / float(count));
      for (int a = 0; a < n; ++a)
        if (eats(a)) eaten[a] += share;
      health = std::max(0.0f, health - share * float(count));
      total += share * float(count);
    }
    int32_t& empty_steps = s.food_respawn[i];
    if (fc.respawn_steps > 0 && empty_steps == fc.respawn_steps) {
      health = float(fc.max_health);
      if (fc.relocate) {
        const auto [x, y] = physics::food_respawn_spot(config_.world.scene, scratch_[env].food_rng);
        p[0] = float(x), p[1] = float(y);
        // This step's vision looked at the old spot: the moved item counts as unseen until the next step's
        // vision (masked in this observation, not eaten at the next step).
        for (int a = 0; a < L.max_agents; ++a) s.vis_food[(size_t(env) * L.max_agents + a) * F + f] = 0;
      }
    }
    empty_steps = health <= 0.0f ? empty_steps + 1 : 0;
  }
  s.stat_run[size_t(env) * Layout::kRunStats + kFoodEaten] += total;
  float hider_units = 0.0f;
  int hiders = 0;
  for (int a = 0; a < n; ++a) {
    hider_units += hider[a] != 0 ? eaten[a] : 0.0f;
    hiders += hider[a];
  }
  const float scale = float(fc.reward_scale);
  for (int a = 0; a < n; ++a) {
    if (hider[a] == 0) continue;
    reward[a] += scale * (fc.joint_mean ? hider_units / float(hiders) : eaten[a]);
  }
}

// The target of agent 0 (docs/game.md §9.2): the nearest unlocked box, or in kSequentialLock the first
// unlocked one in index order; once every box is locked, the spawn point in kLockReturn (kTargetSpawn) and
// none otherwise (kTargetNone). task_dist: the 2-D distance to it.
void BatchSim::lockbox_retarget(int env) {
  const Layout& L = layout_;
  BatchState& s = state_;
  const bool in_order = config_.world.lock_in_order();
  const float* agent = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
  int best = kTargetNone;
  float best_d = 0.0f;
  for (int b = 0; b < L.max_boxes; ++b) {
    const size_t i = size_t(env) * L.max_boxes + b;
    if (s.box_exists[i] == 0 || s.box_locked[i] != 0) continue;
    const float d = std::hypot(s.box_pos[3 * i] - agent[0], s.box_pos[3 * i + 1] - agent[1]);
    if (best < 0 || d < best_d) best = b, best_d = d;
    if (in_order) break;
  }
  if (best == kTargetNone && config_.world.task == physics::WorldConfig::Task::kLockReturn) {
    const float* spawn = s.task_spawn.data() + size_t(env) * 2;
    best = kTargetSpawn;
    best_d = std::hypot(spawn[0] - agent[0], spawn[1] - agent[1]);
  }
  s.task_target[env] = best;
  s.task_dist[env] = best_d;
}

// docs/game.md §9.2 for agent 0 (every agent of the env gets the same reward): +lock_reward per newly locked
// box, -unlock_penalty per newly unlocked one; shaped_reward_scale x the decrease of the 2-D distance to the
// target, +scale x the old distance when the target box gets locked, -scale x the new target's distance when
// a box gets unlocked; +success_reward every step the task is complete: all boxes locked (and in kLockReturn
// agent 0 within return_threshold of its spawn).
void BatchSim::lockbox_rewards_env(int env, float* reward) {
  const Layout& L = layout_;
  BatchState& s = state_;
  const physics::WorldConfig& wc = config_.world;
  const uint8_t* locked = s.box_locked.data() + size_t(env) * L.max_boxes;
  uint8_t* before = s.task_locked.data() + size_t(env) * L.max_boxes;
  int newly_locked = 0, newly_unlocked = 0;
  for (int b = 0; b < L.max_boxes; ++b) {
    newly_locked += locked[b] != 0 && before[b] == 0;
    newly_unlocked += locked[b] == 0 && before[b] != 0;
    before[b] = locked[b];
  }
  double r = wc.lock_reward * newly_locked - wc.unlock_penalty * newly_unlocked;
  const int target = s.task_target[env];
  const double old_dist = s.task_dist[env];
  if (target >= 0 && locked[target] != 0) {
    r += wc.shaped_reward_scale * old_dist;
    lockbox_retarget(env);
  } else if (newly_unlocked > 0) {
    lockbox_retarget(env);
    r -= wc.shaped_reward_scale * s.task_dist[env];
  } else if (target != kTargetNone) {
    lockbox_retarget(env);
    r += wc.shaped_reward_scale * (old_dist - s.task_dist[env]);
  }
  const int now = s.task_target[env];
  if (now == kTargetNone || (now == kTargetSpawn && s.task_dist[env] <= wc.return_threshold)) {
    r += wc.success_reward;
  }
  std::fill_n(reward, L.max_agents, float(r));
}

void BatchSim::measure_env(int env, float out[kNumPrepStats]) const {
  const Layout& L = layout_;
  const BatchState& s = state_;
  auto max_move = [](const float* pos, const float* start, const uint8_t* exists, int n) {
    float best = 0.0f;
    for (int i = 0; i < n; ++i) {
      if (exists[i] == 0) continue;
      const float dx = pos[3 * i] - start[3 * i], dy = pos[3 * i + 1] - start[3 * i + 1];
      const float dz = pos[3 * i + 2] - start[3 * i + 2];
      best = std::max(best, std::sqrt(dx * dx + dy * dy + dz * dz));
    }
    return best;
  };
  auto count = [](const uint8_t* flags, int n) {
    int c = 0;
    for (int i = 0; i < n; ++i) c += flags[i];
    return float(c);
  };
  const size_t b = size_t(env) * L.max_boxes, r = size_t(env) * L.max_ramps;
  out[kBoxMove] = max_move(s.box_pos.data() + (3 * b), s.box_pos_start.data() + (3 * b),
                           s.box_exists.data() + b, L.max_boxes);
  out[kBoxLock] = count(s.box_locked.data() + b, L.max_boxes);
  out[kRampMove] = max_move(s.ramp_pos.data() + (3 * r), s.ramp_pos_start.data() + (3 * r),
                            s.ramp_exists.data() + r, L.max_ramps);
  out[kRampLock] = count(s.ramp_locked.data() + r, L.max_ramps);

  // Doors sealed by the locked boxes (stage_stats.hpp), and doors the boxes cover whether locked or not
  // (boxes moved into the doorways). At most kMaxSealBoxes boxes are looked at: far more than any scene the
  // presets build.
  constexpr int kMaxSealBoxes = 32;
  Footprint locked[kMaxSealBoxes], all[kMaxSealBoxes];
  int num_locked = 0, num_all = 0;
  for (int k = 0; k < L.max_boxes && num_all < kMaxSealBoxes; ++k) {
    if (s.box_exists[b + k] == 0) continue;
    all[num_all++] = box_footprint(env, k);
    if (s.box_locked[b + k] != 0) locked[num_locked++] = all[num_all - 1];
  }
  const physics::Scene& scene = worlds_[env]->scene();
  int sealed = 0, blocked = 0;
  for (const physics::DoorCells& door : scene.doors) {
    const DoorGap gap = door_gap(scene, door);
    sealed += door_sealed(gap, std::span<const Footprint>(locked, size_t(num_locked))) ? 1 : 0;
    blocked += door_sealed(gap, std::span<const Footprint>(all, size_t(num_all))) ? 1 : 0;
  }
  out[kDoorsSealed] = float(sealed);
  out[kDoorsBlocked] = float(blocked);
  bool in_room = false;
  if (scene.layout == physics::Layout::kQuadrant) {
    const Rect room = quadrant_room();
    for (int k = 0; k < L.max_ramps; ++k) {
      const float* p = s.ramp_pos.data() + 3 * (r + k);
      in_room = in_room || (s.ramp_exists[r + k] != 0 && room.contains(p[0], p[1]));
    }
  }
  out[kRampInRoom] = in_room ? 1.0f : 0.0f;
  // The hiders inside the quadrant room (their centres), as a fraction of the hiders.
  int hiders = 0, inside = 0;
  if (scene.layout == physics::Layout::kQuadrant) {
    const Rect room = quadrant_room();
    const size_t ea = size_t(env) * L.max_agents;
    for (int a = 0; a < worlds_[env]->num_agents(); ++a) {
      if (s.agent_hider[ea + a] == 0) continue;
      ++hiders;
      inside += room.contains(s.agent_pos[3 * (ea + a)], s.agent_pos[3 * (ea + a) + 1]) ? 1 : 0;
    }
  }
  out[kHidersInRoom] = hiders > 0 ? float(inside) / float(hiders) : 0.0f;
}

Footprint BatchSim::box_footprint(int env, int box) const {
  const size_t i = size_t(env) * layout_.max_boxes + box;
  const BatchState& s = state_;
  return Footprint{s.box_pos[3 * i],     s.box_pos[3 * i + 1],     s.box_rot[2 * i],
                   s.box_rot[2 * i + 1], 0.5f * s.box_size[3 * i], 0.5f * s.box_size[3 * i + 1]};
}

// The seeking phase's running statistics (stat_run), from this step's mirror and vision.
void BatchSim::track_env(int env, bool any_seen) {
  const Layout& L = layout_;
  BatchState& s = state_;
  const physics::World& world = *worlds_[env];
  const int n = world.num_agents(), A = L.max_agents;
  float* run = s.stat_run.data() + size_t(env) * Layout::kRunStats;
  const size_t ea = size_t(env) * A;
  const float* pos = s.agent_pos.data() + 3 * ea;
  const float* vel = s.agent_vel.data() + 3 * ea;
  const uint8_t* hider = s.agent_hider.data() + ea;
  const uint8_t* vis = s.vis_agents.data() + ea * A;
  run[kSeekSteps] += 1.0f;
  run[kSeenSteps] += any_seen ? 1.0f : 0.0f;

  // Ramps against the interior walls (the 0.5 m ones; outer walls are 4 m high).
  const physics::Scene& scene = world.scene();
  for (int r = 0; r < world.num_ramps(); ++r) {
    const size_t i = size_t(env) * L.max_ramps + r;
    const Footprint ramp{
        s.ramp_pos[3 * i],     s.ramp_pos[3 * i + 1],           s.ramp_rot[2 * i],
        s.ramp_rot[2 * i + 1], float(0.5 * physics::kRampSize), float(0.5 * physics::kRampSize)};
    for (const physics::StaticBox& w : scene.wall_boxes) {
      if (2.0 * w.hz > physics::kInteriorWallHeight + 1e-6) continue;
      run[kRampWallDist] = std::min(run[kRampWallDist], footprint_distance(ramp, footprint_of(w)));
    }
  }

  bool surfing = false;
  for (int sk = 0; sk < n; ++sk) {
    if (hider[sk] != 0) continue;
    const float* p = pos + 3 * sk;
    // Approach: the seeker's horizontal velocity towards its nearest hider.
    int nearest = -1;
    float best = 0.0f;
    bool sees_hider = false;
    for (int h = 0; h < n; ++h) {
      if (hider[h] == 0) continue;
      sees_hider = sees_hider || vis[sk * A + h] != 0;
      const float d = std::hypot(pos[3 * h] - p[0], pos[3 * h + 1] - p[1]);
      if (nearest < 0 || d < best) nearest = h, best = d;
    }
    if (nearest >= 0 && best > 1e-6f) {
      const float* q = pos + 3 * nearest;
      run[kApproachSum] += (vel[3 * sk] * (q[0] - p[0]) + vel[3 * sk + 1] * (q[1] - p[1])) / best;
      run[kApproachCount] += 1.0f;
    }
    if (sees_hider && p[2] > kHighAgentZ) run[kHighSeen] = 1.0f;
    // Surfing: standing on a box that slides.
    for (int k = 0; k < world.num_boxes() && !surfing; ++k) {
      const size_t i = size_t(env) * L.max_boxes + k;
      const float* v = s.box_vel.data() + 3 * i;
      if (std::hypot(v[0], v[1]) < kSurfSpeed) continue;
      const float top = s.box_pos[3 * i + 2] + 0.5f * s.box_size[3 * i + 2];
      surfing = stands_on(box_footprint(env, k), top, p[0], p[1], p[2]);
    }
  }
  run[kSurfCount] += surfing ? 1.0f : 0.0f;
}

// Records the finished episode's statistics and starts the env's next episode.
void BatchSim::end_episode_env(int env, bool discarded) {
  BatchState& s = state_;
  EnvScratch& sc = scratch_[env];
  EpisodeStats& st = sc.stats;
  const float* prep = s.stat_prep.data() + size_t(env) * Layout::kPrepStats;
  const float* run = s.stat_run.data() + size_t(env) * Layout::kRunStats;
  float end[Layout::kPrepStats];
  measure_env(env, end);
  st.env = env;
  st.episode = s.episode[env];
  st.length = worlds_[env]->step_count();
  st.discarded = discarded;
  st.hider_return = s.episode_return[size_t(env) * 2];
  st.seeker_return = s.episode_return[size_t(env) * 2 + 1];
  st.max_box_move_prep = prep[kBoxMove];
  st.num_box_lock_prep = prep[kBoxLock];
  st.max_ramp_move_prep = prep[kRampMove];
  st.num_ramp_lock_prep = prep[kRampLock];
  st.max_box_move = end[kBoxMove];
  st.num_box_lock = end[kBoxLock];
  st.max_ramp_move = end[kRampMove];
  st.num_ramp_lock = end[kRampLock];
  st.num_doors = float(worlds_[env]->scene().doors.size());
  st.num_door_sealed_prep = prep[kDoorsSealed];
  st.num_door_sealed = end[kDoorsSealed];
  st.hider_seen_frac = run[kSeekSteps] > 0 ? run[kSeenSteps] / run[kSeekSteps] : 0.0f;
  st.seeker_approach = run[kApproachCount] > 0 ? run[kApproachSum] / run[kApproachCount] : 0.0f;
  st.ramp_wall_dist = run[kRampWallDist];
  st.seeker_high_seen = run[kHighSeen];
  st.ramp_in_room_prep = prep[kRampInRoom];
  st.num_door_blocked_prep = prep[kDoorsBlocked];
  st.hiders_in_room_prep = prep[kHidersInRoom];
  st.box_surf = run[kSurfCount] >= float(kSurfSteps) ? 1.0f : 0.0f;
  st.food_eaten = run[kFoodEaten];
  st.max_agent_move = 0.0f;
  for (int a = 0; a < worlds_[env]->num_agents(); ++a) {
    const size_t i = (size_t(env) * layout_.max_agents + a) * 3;
    const float dx = s.agent_pos[i] - s.agent_pos_start[i],
                dy = s.agent_pos[i + 1] - s.agent_pos_start[i + 1];
    const float dz = s.agent_pos[i + 2] - s.agent_pos_start[i + 2];
    st.max_agent_move = std::max(st.max_agent_move, std::sqrt(dx * dx + dy * dy + dz * dz));
  }
  sc.finished = true;
  if (!final_.empty() && !discarded) {
    // The episode's last observation, before the reset below replaces it.
    observe_env(env);
    for (FinalField& f : final_) {
      const size_t at = size_t(env) * f.env_bytes;
      std::memcpy(f.copy.data() + at, f.source + at, f.env_bytes);
    }
    final_mask_[size_t(env)] = 1;
  }
  reset_env(env, uint64_t(s.episode[env]) + 1);
  s.done[env] = 1;
}

// Observation tensors of every agent of the env (docs/game.md §4.3-§4.6, §14.1). Other agents come in
// circulant order i-1, i-2, ... (mod n); boxes and ramps in index order; padding slots are zero with mask 0.
void BatchSim::observe_env(int env) {
  const Layout& L = layout_;
  BatchState& s = state_;
  const physics::World& world = *worlds_[env];
  const int A = L.max_agents, B = L.max_boxes, R = L.max_ramps, O = L.others;
  const int n = world.num_agents(), nb = world.num_boxes(), nr = world.num_ramps();
  const size_t ea = size_t(env) * A;
  float* obs_self = s.obs_self.data() + ea * Layout::kSelfFeatures;
  float* obs_agents = s.obs_agents.data() + ea * O * Layout::kAgentFeatures;
  uint8_t* mask_agents = s.mask_agents.data() + ea * O;
  uint8_t* value_mask_agents = s.value_mask_agents.data() + ea * O;
  float* obs_boxes = s.obs_boxes.data() + ea * B * Layout::kBoxFeatures;
  uint8_t* mask_boxes = s.mask_boxes.data() + ea * B;
  uint8_t* value_mask_boxes = s.value_mask_boxes.data() + ea * B;
  float* obs_ramps = s.obs_ramps.data() + ea * R * Layout::kRampFeatures;
  uint8_t* mask_ramps = s.mask_ramps.data() + ea * R;
  uint8_t* value_mask_ramps = s.value_mask_ramps.data() + ea * R;
  const int C = L.max_sites, CS = L.construction_sites, F = L.max_food, SF = L.site_features;
  float* obs_sites = s.obs_sites.data() + ea * C * SF;
  uint8_t* eat_ok = s.food_eat_ok.data() + ea * F;
  std::fill_n(eat_ok, size_t(A) * F, 0);
  uint8_t* mask_sites = s.mask_sites.data() + ea * C;
  uint8_t* value_mask_sites = s.value_mask_sites.data() + ea * C;
  std::fill_n(obs_self, size_t(A) * Layout::kSelfFeatures, 0.0f);
  std::fill_n(obs_agents, size_t(A) * O * Layout::kAgentFeatures, 0.0f);
  std::fill_n(mask_agents, size_t(A) * O, 0);
  std::fill_n(value_mask_agents, size_t(A) * O, 0);
  std::fill_n(obs_boxes, size_t(A) * B * Layout::kBoxFeatures, 0.0f);
  std::fill_n(mask_boxes, size_t(A) * B, 0);
  std::fill_n(value_mask_boxes, size_t(A) * B, 0);
  std::fill_n(obs_ramps, size_t(A) * R * Layout::kRampFeatures, 0.0f);
  std::fill_n(mask_ramps, size_t(A) * R, 0);
  std::fill_n(value_mask_ramps, size_t(A) * R, 0);
  std::fill_n(obs_sites, size_t(A) * C * SF, 0.0f);
  std::fill_n(mask_sites, size_t(A) * C, 0);
  std::fill_n(value_mask_sites, size_t(A) * C, 0);

  const float prep_obs = prep_observation(s.step_count[env], config_.world.prep_steps());
  const float* pos = s.agent_pos.data() + ea * 3;
  const float* rot = s.agent_rot.data() + ea * 2;
  const float* vel = s.agent_vel.data() + ea * 3;
  const float* angvel = s.agent_angvel.data() + ea;
  const uint8_t* hider = s.agent_hider.data() + ea;
  auto agent_features = [&](int j, float* out) {
    out[0] = pos[3 * j], out[1] = pos[3 * j + 1], out[2] = pos[3 * j + 2];
    out[3] = rot[2 * j], out[4] = rot[2 * j + 1];
    out[5] = vel[3 * j], out[6] = vel[3 * j + 1], out[7] = vel[3 * j + 2];
    out[8] = angvel[j];
    out[9] = float(hider[j]);
    out[10] = prep_obs;
  };
  // Lock features of an object for agent a: it locked it, its team did, it is locked (docs/game.md §3.4).
  auto lock_features = [&](bool locked, int locker, int a, float* out) {
    out[0] = locked && locker == a ? 1.0f : 0.0f;
    out[1] = locked && locker >= 0 && hider[locker] == hider[a] ? 1.0f : 0.0f;
    out[2] = locked ? 1.0f : 0.0f;
  };
  const uint8_t* vis_agents = s.vis_agents.data() + ea * A;
  const uint8_t* vis_boxes = s.vis_boxes.data() + ea * B;
  const uint8_t* vis_ramps = s.vis_ramps.data() + ea * R;
  const uint8_t* vis_food = s.vis_food.data() + ea * F;
  // No hider is seen by a seeker in this observation (the food variants' eating mask).
  bool eat_free = true;
  for (int sk = 0; sk < n && F > 0; ++sk) {
    if (hider[sk] != 0) continue;
    for (int h = 0; h < n; ++h) eat_free = eat_free && !(hider[h] != 0 && vis_agents[sk * A + h] != 0);
  }
  const int hider_obs = config_.world.obs_hider;
  for (int a = 0; a < n; ++a) {
    agent_features(a, obs_self + a * Layout::kSelfFeatures);
    if (hider_obs >= 0) obs_self[a * Layout::kSelfFeatures + 9] = float(hider_obs);
    for (int k = 0; k < n - 1; ++k) {
      const int j = ((a - 1 - k) % n + n) % n;
      agent_features(j, obs_agents + (size_t(a) * O + k) * Layout::kAgentFeatures);
      mask_agents[a * O + k] = vis_agents[a * A + j];
      value_mask_agents[a * O + k] = 1;
    }
    for (int b = 0; b < nb; ++b) {
      const size_t i = size_t(env) * B + b;
      float* out = obs_boxes + (size_t(a) * B + b) * Layout::kBoxFeatures;
      std::copy_n(s.box_pos.data() + (3 * i), 3, out);
      std::copy_n(s.box_rot.data() + (2 * i), 2, out + 3);
      std::copy_n(s.box_vel.data() + (3 * i), 3, out + 5);
      out[8] = s.box_angvel[i];
      std::copy_n(s.box_size.data() + (3 * i), 3, out + 9);
      lock_features(s.box_locked[i] != 0, s.box_locker[i], a, out + 12);
      mask_boxes[a * B + b] = vis_boxes[a * B + b];
      value_mask_boxes[a * B + b] = 1;
    }
    for (int r = 0; r < nr; ++r) {
      const size_t i = size_t(env) * R + r;
      float* out = obs_ramps + (size_t(a) * R + r) * Layout::kRampFeatures;
      std::copy_n(s.ramp_pos.data() + (3 * i), 3, out);
      std::copy_n(s.ramp_rot.data() + (2 * i), 2, out + 3);
      std::copy_n(s.ramp_vel.data() + (3 * i), 3, out + 5);
      out[8] = s.ramp_angvel[i];
      lock_features(s.ramp_locked[i] != 0, s.ramp_locker[i], a, out + 9);
      mask_ramps[a * R + r] = vis_ramps[a * R + r];
      value_mask_ramps[a * R + r] = 1;
    }
    // Construction sites (docs/game.md §9.1): centre, then the corners (-,-), (+,-), (+,+), (-,+); always
    // visible.
    for (int c = 0; c < CS; ++c) {
      const size_t i = size_t(env) * CS + c;
      if (s.site_exists[i] == 0) continue;
      float* out = obs_sites + (size_t(a) * C + c) * SF;
      const float* p = s.site_pos.data() + 3 * i;
      std::copy_n(p, 3, out);
      constexpr float kHalf = float(0.5 * physics::kSiteSize);
      constexpr float kSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
      for (int k = 0; k < 4; ++k) {
        out[3 + 3 * k] = p[0] + kSigns[k][0] * kHalf;
        out[4 + 3 * k] = p[1] + kSigns[k][1] * kHalf;
        out[5 + 3 * k] = p[2];
      }
      mask_sites[a * C + c] = 1;
      value_mask_sites[a * C + c] = 1;
    }
    // Food (docs/game.md §5.4): position and health, seen through vision; a hider may eat what it sees while
    // no hider is seen (unless eat_when_caught), which the next step's eating reads.
    for (int f = 0; f < F; ++f) {
      const size_t i = size_t(env) * F + f;
      if (s.food_exists[i] == 0) continue;
      float* out = obs_sites + (size_t(a) * C + f) * SF;
      std::copy_n(s.food_pos.data() + 3 * i, 3, out);
      out[3] = s.food_health[i];
      const uint8_t seen = vis_food[a * F + f];
      mask_sites[a * C + f] = seen;
      value_mask_sites[a * C + f] = 1;
      eat_ok[a * F + f] =
          hider[a] != 0 && seen != 0 && (eat_free || config_.world.food.eat_when_caught) ? 1 : 0;
    }
  }
}

}  // namespace hns::batch
