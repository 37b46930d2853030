// BatchSim, the driver of a batch: builds the worlds, runs each env's step through the stages in the order
// batch_sim.hpp states (TBB over fixed ranges of envs, so that results do not depend on the thread count),
// times and traces the phases, starts and ends episodes and keeps final observations. The stages are free
// functions of one env (env.hpp lists them and their files).
#include "batch/batch_sim.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <stdexcept>

#include "batch/tasks/task.hpp"

namespace hns::batch {
namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

// Per-env bookkeeping that is not part of the observable state.
struct BatchSim::EnvScratch {
  bool finished = false;  // an episode ended during the last step
  EpisodeStats stats;
  int64_t unstable_resets = 0;
  int64_t ns_physics = 0, ns_mirror = 0, ns_perception = 0, ns_observations = 0, ns_rewards = 0;
  std::vector<TraceEvent> trace;  // filled only while tracing
  physics::Rng task_rng;          // the rules' random stream (EnvRef::rng)
};

EnvRef BatchSim::env_ref(int env) {
  return EnvRef{config_, layout_, state_, *worlds_[env], env, *task_, scratch_[env].task_rng};
}

BatchSim::BatchSim(const BatchConfig& config) : config_(config), epoch_(std::chrono::steady_clock::now()) {
  config_.validate();
  config_.world.compute_visibility = false;  // the batch's SIMD vision fills it
  layout_ = Layout::of(config_);
  task_ = config_.rules.task;
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
            EnvRef ref = env_ref(e);
            observe(ref);
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
    EnvRef ref = env_ref(e);
    if (task_->scripted()) {
      // Object counting: the agent's actions are ignored and the script sets every pose after the step.
      const AgentAction idle[1] = {};
      world.step(std::span<const AgentAction>(idle, size_t(world.num_agents())));
    } else {
      world.step(actions.subspan(size_t(e) * A, size_t(world.num_agents())));
    }
    task_->after_physics(ref);
    phase_done("physics", sc.ns_physics);
    if (world.unstable()) {
      // Numerical trouble stays in this env: drop the episode, start a new one.
      ++sc.unstable_resets;
      std::fill_n(state_.reward.data() + size_t(e) * A, A, 0.0f);
      end_episode_env(e, true);
      phase_done("rewards+resets", sc.ns_rewards);
    } else {
      mirror(ref);
      build_shapes(ref);
      phase_done("mirror", sc.ns_mirror);
      vision(ref);
      lidar(ref);
      phase_done("vision+lidar", sc.ns_perception);
      state_.step_count[e] = world.step_count();
      task_->reward_and_done(ref);
      if (state_.done[e] != 0) end_episode_env(e, false);
      phase_done("rewards+resets", sc.ns_rewards);
    }
    observe(ref);
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
  EnvRef ref = env_ref(env);
  observe(ref);
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
  const int nc = int(scene.sites.size()), nf = int(scene.food.size());
  if (nc > layout_.construction_sites || nf > layout_.max_food) {
    throw std::logic_error("scene has " + std::to_string(nc) + " construction sites and " +
                           std::to_string(nf) + " food items, layout allows " +
                           std::to_string(layout_.construction_sites) + " and " +
                           std::to_string(layout_.max_food));
  }
  state_.episode[env] = int32_t(episode);
  state_.step_count[env] = 0;
  state_.num_walls[env] = int32_t(scene.wall_boxes.size());
  std::fill_n(state_.stat_prep.data() + size_t(env) * Layout::kPrepStats, Layout::kPrepStats, 0.0f);
  float* run = state_.stat_run.data() + size_t(env) * Layout::kRunStats;
  std::fill_n(run, Layout::kRunStats, 0.0f);
  run[kRampWallDist] = float(physics::kFloorSize);
  std::fill_n(state_.episode_return.data() + size_t(env) * 2, 2, 0.0f);
  state_.task_complete[env] = 0;
  EnvRef ref = env_ref(env);
  build_static_shapes(ref);
  task_->start_episode(ref, episode);
  refresh_env(env);
  std::copy_n(state_.box_pos.data() + size_t(env) * layout_.max_boxes * 3, layout_.max_boxes * 3,
              state_.box_pos_start.data() + size_t(env) * layout_.max_boxes * 3);
  std::copy_n(state_.ramp_pos.data() + size_t(env) * layout_.max_ramps * 3, layout_.max_ramps * 3,
              state_.ramp_pos_start.data() + size_t(env) * layout_.max_ramps * 3);
  std::copy_n(state_.agent_pos.data() + size_t(env) * layout_.max_agents * 3, layout_.max_agents * 3,
              state_.agent_pos_start.data() + size_t(env) * layout_.max_agents * 3);
  task_->episode_started(ref);
}

void BatchSim::resync(int env) {
  refresh_env(env);
  EnvRef ref = env_ref(env);
  observe(ref);
}

void BatchSim::refresh_env(int env) {
  EnvRef ref = env_ref(env);
  mirror(ref);
  build_shapes(ref);
  vision(ref);
  lidar(ref);
}

void BatchSim::compute_vision(int env) {
  EnvRef ref = env_ref(env);
  vision(ref);
}

void BatchSim::compute_lidar(int env) {
  EnvRef ref = env_ref(env);
  lidar(ref);
}

void BatchSim::compute_observations(int env) {
  EnvRef ref = env_ref(env);
  observe(ref);
}

ShapesView BatchSim::shapes(int env) const {
  return shapes_view(layout_, state_, *worlds_[env], env);
}

int BatchSim::shelter_rays_reaching(int env) const {
  return ::hns::batch::shelter_rays_reaching(layout_, state_, *worlds_[env], env);
}

// Records the finished episode's statistics and starts the env's next episode.
void BatchSim::end_episode_env(int env, bool discarded) {
  EnvScratch& sc = scratch_[env];
  EnvRef ref = env_ref(env);
  record_episode(ref, discarded, sc.stats);
  sc.finished = true;
  if (!final_.empty() && !discarded) {
    // The episode's last observation, before the reset below replaces it.
    observe(ref);
    for (FinalField& f : final_) {
      const size_t at = size_t(env) * f.env_bytes;
      std::memcpy(f.copy.data() + at, f.source + at, f.env_bytes);
    }
    final_mask_[size_t(env)] = 1;
  }
  reset_env(env, uint64_t(state_.episode[env]) + 1);
  state_.done[env] = 1;
}

}  // namespace hns::batch
