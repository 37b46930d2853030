// BatchSim: many hide-and-seek worlds stepped together, their state mirrored as structure-of-arrays, with
// vision, lidar, observations, rewards, statistics and auto-reset (docs/game.md §3-§7, §14).
//
// One step, per env (TBB over fixed ranges of envs; step_range() is the same code run serially):
//   actions[env, agent] -> World::step (grab, lock, substeps) -> mirror bodies into the SoA fields
//   -> shapes for ray casts -> vision (cone + line of sight) and lidar -> the game's rules: rewards, dones,
//   statistics -> auto-reset of finished envs (new scene from the env's own stream) -> observation tensors
// The game's rules are its Task (tasks/task.hpp, one file per game), the other stages free functions of one
// env (env.hpp lists them and their files).
#pragma once

#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "batch/game.hpp"
#include "batch/ray_kernels.hpp"
#include "batch/stage_stats.hpp"
#include "common/aligned_buffer.hpp"
#include "physics/world.hpp"

namespace hns::batch {

using physics::AgentAction;
struct EnvRef;
class Task;

// A batch: the game its envs play (the world and the rules; a scene's preset sets both, batch/scenes.hpp)
// and how it runs. The defaults play the quadrant game.
struct BatchConfig {
  physics::WorldConfig world = physics::WorldConfig::quadrant();
  GameRules rules;
  int num_envs = 64;
  int threads = 1;    // TBB worker threads used by step()
  uint64_t seed = 1;  // env e's episode k is drawn from (seed, first_env + e, k)
  // Index of this batch's first env in a larger run (a slice of it stepped by one process): env e plays
  // exactly what env first_env + e of one batch of all the envs would.
  int64_t first_env = 0;
  // Agent slots per env: the world's max_agents(), at least rules.obs_min_agents (Layout's max_agents).
  int agent_slots() const { return std::max(world.max_agents(), rules.obs_min_agents); }
  int envs_per_task = 4;  // fixed work partition, independent of the thread count
  // Throws physics::ConfigError naming the first bad field: the world's, then the rules', then the batch's.
  void validate() const;
  // Estimated memory of a BatchSim of this config, bytes: its state plus each env's world (ODE bodies,
  // geoms, solver scratch), from measurements (within about 25 %).
  size_t estimated_bytes() const;
};

// Slots of the stat_prep field: what the episode statistics read from the mirror when the preparation phase
// ends (and again when the episode ends): docs/game.md §7's max box move (m), boxes locked, max ramp move
// (m), ramps locked, then the doors sealed by locked boxes, whether a ramp is in the quadrant room (1 or
// 0), the doors covered by boxes, the fraction of the hiders in the quadrant room and the fraction of the
// hiders beside a locked box (hider_screened).
enum PrepStat {
  kBoxMove,
  kBoxLock,
  kRampMove,
  kRampLock,
  kDoorsSealed,
  kRampInRoom,
  kDoorsBlocked,
  kHidersInRoom,
  kHidersScreened,
  kNumPrepStats
};
// Slots of the stat_run field: the seeking phase's running statistics. The closest a ramp came to an
// interior wall (m, starts at 6); 1 once a seeker above a wall saw a hider; steps in which a hider was seen;
// seeking-phase steps; the sum and count of the seekers' speeds towards their nearest hider (m/s); steps in
// which a seeker stood on a sliding box; food units the hiders ate; 1 once a seeker stood above a wall.
enum RunStat {
  kRampWallDist,
  kHighSeen,
  kSeenSteps,
  kSeekSteps,
  kApproachSum,
  kApproachCount,
  kSurfCount,
  kFoodEaten,
  kSeekerHigh,
  kNumRunStats
};

// task_target values other than a box index.
inline constexpr int32_t kTargetNone = -1;   // every box is locked, nothing left to do
inline constexpr int32_t kTargetSpawn = -2;  // lock-and-return: every box is locked, go back to the spawn

// Per-env sizes of every tensor, fixed per batch by the config's maxima.
struct Layout {
  int max_agents = 0;  // A
  int max_boxes = 0;   // B
  int max_ramps = 0;   // R
  // C: the networks' fourth entity type, blueprint's construction sites or the food (0 in other scenes),
  // of site_features floats each (kConstructionSiteFeatures or kFoodFeatures).
  int max_sites = 0;
  int site_features = 0;
  int max_food = 0;                          // F: food items (C = F in the food variants)
  int construction_sites = 0;                // CS: blueprint's construction sites (C = CS in blueprint)
  int max_walls = 0;                         // walls a scene may have
  int others = 0;                            // A - 1 other-agent slots
  int shape_boxes = 0;                       // ray-cast shape slots: walls + boxes
  int shape_wedges = 0;                      // ramps
  int shape_spheres = 0;                     // agents and their arms: kSpheresPerAgent slots each
  int shape_cylinders = 0;                   // the shelter task's static cylinder: 1 or 0
  static constexpr int kSelfFeatures = 11;   // pos 3, cos/sin yaw, vel 3, ang vel, hider, prep
  static constexpr int kAgentFeatures = 11;  // the same for another agent
  static constexpr int kBoxFeatures = 15;    // pos 3, cos/sin, vel 3, ang vel, size 3, you/team/obj lock
  static constexpr int kRampFeatures = 12;   // pos 3, cos/sin, vel 3, ang vel, you/team/obj lock
  static constexpr int kConstructionSiteFeatures = 15;  // centre 3, then 4 corners x 3 (docs/game.md §9.1)
  static constexpr int kFoodFeatures = 4;               // position 3, health (docs/game.md §5.4)
  static constexpr int kLidar = 30;
  static constexpr int kSpheresPerAgent = 3;  // body, left arm, right arm (docs/game.md §1.2)
  static constexpr int kPrepStats = kNumPrepStats;
  static constexpr int kRunStats = kNumRunStats;

  // The sizes of a batch of this config.
  static Layout of(const BatchConfig& config);
  // Bytes of BatchState per env.
  size_t state_bytes_per_env() const;
};

// Every per-env field of the batch: X(type, name, elements per env, doc). Env index outermost; one
// aligned buffer per field; slots beyond an episode's counts are zero and masked out.
#define HNS_BATCH_FIELDS(X)                                                                                 \
  /* Bodies, true centres (docs/game.md §14.1). */                                                         \
  X(float, agent_pos, L.max_agents * 3, "agent centre, m (envs x A x 3)")                                   \
  X(float, agent_rot, L.max_agents * 2, "agent yaw as (cos, sin) (envs x A x 2)")                           \
  X(float, agent_vel, L.max_agents * 3, "agent velocity, m/s (envs x A x 3)")                               \
  X(float, agent_angvel, L.max_agents, "agent angular velocity about z, rad/s (envs x A)")                  \
  X(uint8_t, agent_exists, L.max_agents, "1 if the slot holds an agent this episode (envs x A)")            \
  X(uint8_t, agent_hider, L.max_agents, "1 for hiders, 0 for seekers (envs x A)")                           \
  X(float, box_pos, L.max_boxes * 3, "box centre, m (envs x B x 3)")                                        \
  X(float, box_rot, L.max_boxes * 2, "box yaw as (cos, sin) (envs x B x 2)")                                \
  X(float, box_vel, L.max_boxes * 3, "box velocity, m/s (envs x B x 3)")                                    \
  X(float, box_angvel, L.max_boxes, "box angular velocity, rad/s (envs x B)")                               \
  X(float, box_size, L.max_boxes * 3, "box full extents, m (envs x B x 3)")                                 \
  X(uint8_t, box_exists, L.max_boxes, "1 if the box slot is used (envs x B)")                               \
  X(uint8_t, box_locked, L.max_boxes, "1 if pinned (envs x B)")                                             \
  X(int8_t, box_locker, L.max_boxes, "agent that locked it last, -1 never (envs x B)")                      \
  X(float, ramp_pos, L.max_ramps * 3, "ramp bounding-box centre, m (envs x R x 3)")                         \
  X(float, ramp_rot, L.max_ramps * 2, "ramp yaw as (cos, sin) (envs x R x 2)")                              \
  X(float, ramp_vel, L.max_ramps * 3, "ramp velocity, m/s (envs x R x 3)")                                  \
  X(float, ramp_angvel, L.max_ramps, "ramp angular velocity, rad/s (envs x R)")                             \
  X(uint8_t, ramp_exists, L.max_ramps, "1 if the ramp slot is used (envs x R)")                             \
  X(uint8_t, ramp_locked, L.max_ramps, "1 if pinned (envs x R)")                                            \
  X(int8_t, ramp_locker, L.max_ramps, "agent that locked it last, -1 never (envs x R)")                     \
  X(float, site_pos, L.construction_sites * 3, "construction site centre, m (envs x CS x 3)")               \
  X(uint8_t, site_exists, L.construction_sites, "1 if the site slot is used (envs x CS)")                   \
  X(float, food_pos, L.max_food * 3, "food item centre, m (envs x F x 3)")                                  \
  X(float, food_health, L.max_food, "food units left in the item (envs x F)")                               \
  X(int32_t, food_respawn, L.max_food, "steps the item has been eaten up (envs x F)")                       \
  X(uint8_t, food_exists, L.max_food, "1 if the food slot is used (envs x F)")                              \
  X(uint8_t, food_eat_ok, L.max_agents* L.max_food,                                                         \
    "agent may eat the item at the next step: a hider that sees it while no hider is seen (envs x A x F)")  \
  X(float, food_eaten, L.max_agents, "food units the agent ate in the last step (envs x A)")                \
  /* Shapes for ray casts: walls then boxes, ramps, agents; padding parked below the floor. */              \
  X(float, shape_box_cx, L.shape_boxes, "box-shaped occluder centre x, m (envs x SB)")                      \
  X(float, shape_box_cy, L.shape_boxes, "centre y, m")                                                      \
  X(float, shape_box_cz, L.shape_boxes, "centre z, m")                                                      \
  X(float, shape_box_hx, L.shape_boxes, "half extent x, m")                                                 \
  X(float, shape_box_hy, L.shape_boxes, "half extent y, m")                                                 \
  X(float, shape_box_hz, L.shape_boxes, "half extent z, m")                                                 \
  X(float, shape_box_c, L.shape_boxes, "cos yaw")                                                           \
  X(float, shape_box_s, L.shape_boxes, "sin yaw")                                                           \
  X(float, shape_wedge_cx, L.shape_wedges, "ramp occluder centre x, m (envs x SW)")                         \
  X(float, shape_wedge_cy, L.shape_wedges, "centre y, m")                                                   \
  X(float, shape_wedge_cz, L.shape_wedges, "centre z, m")                                                   \
  X(float, shape_wedge_c, L.shape_wedges, "cos yaw")                                                        \
  X(float, shape_wedge_s, L.shape_wedges, "sin yaw")                                                        \
  X(float, shape_sphere_cx, L.shape_spheres, "agent body, arm, arm centre x, m (envs x SS = A x 3)")        \
  X(float, shape_sphere_cy, L.shape_spheres, "centre y, m")                                                 \
  X(float, shape_sphere_cz, L.shape_spheres, "centre z, m")                                                 \
  X(float, shape_sphere_r, L.shape_spheres, "radius, m")                                                    \
  X(float, shape_cyl_cx, L.shape_cylinders, "shelter cylinder's axis x, m (envs x SC, SC = 0 or 1)")        \
  X(float, shape_cyl_cy, L.shape_cylinders, "axis y, m")                                                    \
  X(float, shape_cyl_r, L.shape_cylinders, "radius, m")                                                     \
  X(float, shape_cyl_h, L.shape_cylinders, "height, m (it stands on the floor)")                            \
  X(int32_t, num_walls, 1, "walls of this episode's scene (envs)")                                          \
  /* Perception (docs/game.md §4.1, §4.2). */                                                             \
  X(uint8_t, vis_agents, L.max_agents* L.max_agents, "agent i sees agent j, diagonal 1 (envs x A x A)")     \
  X(uint8_t, vis_boxes, L.max_agents* L.max_boxes, "agent sees box (envs x A x B)")                         \
  X(uint8_t, vis_ramps, L.max_agents* L.max_ramps, "agent sees ramp (envs x A x R)")                        \
  X(uint8_t, vis_food, L.max_agents* L.max_food, "agent sees food item (envs x A x F)")                     \
  X(float, lidar, L.max_agents* Layout::kLidar, "lidar distance, m, 6 = nothing (envs x A x 30)")           \
  /* Step outputs (docs/game.md §5). */                                                                    \
  X(float, reward, L.max_agents, "reward of the last step (envs x A)")                                      \
  X(uint8_t, done, 1, "1 if the last step ended the episode; the obs is then the new episode's first")      \
  X(int32_t, step_count, 1, "env steps taken in the current episode (envs)")                                \
  X(int32_t, episode, 1, "episode number of the env (envs)")                                                \
  /* Episode statistics (docs/game.md §7). */                                                              \
  X(float, box_pos_start, L.max_boxes * 3, "box centre at reset, m (envs x B x 3)")                         \
  X(float, agent_pos_start, L.max_agents * 3, "agent centre at reset, m (envs x A x 3)")                    \
  X(float, ramp_pos_start, L.max_ramps * 3, "ramp centre at reset, m (envs x R x 3)")                       \
  X(float, stat_prep, Layout::kPrepStats, "measured when prep ends, slots PrepStat (envs x 9)")             \
  X(float, stat_run, Layout::kRunStats, "seeking phase's running statistics, slots RunStat (envs x 9)")     \
  X(float, episode_return, 2, "this episode's summed mean reward of hiders, of seekers (envs x 2)")         \
  /* Box-locking tasks (tasks/lock_tasks.cpp, docs/game.md §9.2). */                                       \
  X(int32_t, task_target, 1, "agent 0's target box, kTargetSpawn or kTargetNone (all locked) (envs)")       \
  X(float, task_dist, 1, "agent 0's 2-D distance to its target at the last step, m (envs)")                 \
  X(float, task_spawn, 2, "agent 0's spawn x, y, m: the target of lock-and-return's return (envs x 2)")     \
  X(uint8_t, task_locked, L.max_boxes, "box locked at the last step (envs x B)")                            \
  X(uint8_t, task_complete, 1, "blueprint: 1 from the completing step on; later steps are absorbed (envs)") \
  /* Observations per agent (docs/game.md §4.3-§4.6 with §14.1). */                                      \
  X(float, obs_self, L.max_agents* Layout::kSelfFeatures, "own features (envs x A x 11)")                   \
  X(float, obs_agents, L.max_agents* L.others* Layout::kAgentFeatures,                                      \
    "other agents in circulant order (envs x A x A-1 x 11)")                                                \
  X(uint8_t, mask_agents, L.max_agents* L.others, "policy mask: other agent seen (envs x A x A-1)")         \
  X(uint8_t, value_mask_agents, L.max_agents* L.others, "value mask: other agent exists (envs x A x A-1)")  \
  X(float, obs_boxes, L.max_agents* L.max_boxes* Layout::kBoxFeatures, "boxes (envs x A x B x 15)")         \
  X(uint8_t, mask_boxes, L.max_agents* L.max_boxes, "policy mask: box seen (envs x A x B)")                 \
  X(uint8_t, value_mask_boxes, L.max_agents* L.max_boxes, "value mask: box exists (envs x A x B)")          \
  X(float, obs_ramps, L.max_agents* L.max_ramps* Layout::kRampFeatures, "ramps (envs x A x R x 12)")        \
  X(uint8_t, mask_ramps, L.max_agents* L.max_ramps, "policy mask: ramp seen (envs x A x R)")                \
  X(uint8_t, value_mask_ramps, L.max_agents* L.max_ramps, "value mask: ramp exists (envs x A x R)")         \
  X(float, obs_sites, L.max_agents* L.max_sites* L.site_features,                                           \
    "construction sites (centre, 4 corners) or food (position, health) (envs x A x C x 15 or 4)")           \
  X(uint8_t, mask_sites, L.max_agents* L.max_sites, "policy mask: site exists, food seen (envs x A x C)")   \
  X(uint8_t, value_mask_sites, L.max_agents* L.max_sites, "value mask: site or food exists (envs x A x C)")

// The batch state: one aligned buffer per field, sized num_envs x (elements per env).
struct BatchState {
#define HNS_DECLARE_FIELD(type, name, count, doc) AlignedBuffer<type> name;
  HNS_BATCH_FIELDS(HNS_DECLARE_FIELD)
#undef HNS_DECLARE_FIELD

  void allocate(const Layout& L, int num_envs);
  // Calls f(name, span_of_bytes) for every field, in declaration order (copy, compare, checksum).
  template <class F>
  void for_each_field(F&& f) const {
#define HNS_VISIT_FIELD(type, name, count, doc) \
  f(#name,                                      \
    std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(name.data()), name.size() * sizeof(type)));
    HNS_BATCH_FIELDS(HNS_VISIT_FIELD)
#undef HNS_VISIT_FIELD
  }
};

// Per-episode statistics after the returns, in this order: X(name, doc). docs/game.md §7's eight, then the
// direct stage detectors (docs/training.md "Stages"). Each is a float of EpisodeStats, the mean over an
// iteration's episodes in metrics.jsonl, and a key of the Python module's finished episodes.
#define HNS_EPISODE_STATS(X)                                                                                \
  X(max_box_move_prep, "m, largest box displacement from its spawn at the end of the preparation phase")    \
  X(num_box_lock_prep, "boxes locked at the end of the preparation phase")                                  \
  X(max_ramp_move_prep, "m, largest ramp displacement at the end of the preparation phase")                 \
  X(num_ramp_lock_prep, "ramps locked at the end of the preparation phase")                                 \
  X(max_box_move, "m, largest box displacement at the end of the episode")                                  \
  X(num_box_lock, "boxes locked at the end of the episode")                                                 \
  X(max_ramp_move, "m, largest ramp displacement at the end of the episode")                                \
  X(num_ramp_lock, "ramps locked at the end of the episode")                                                \
  X(num_doors, "doors in the episode's walls")                                                              \
  X(num_door_sealed_prep, "doors sealed by locked boxes at the end of the preparation phase (door_sealed)") \
  X(num_door_sealed, "doors sealed by locked boxes at the end of the episode")                              \
  X(hider_seen_frac, "fraction of the seeking phase's steps in which a seeker saw a hider")                 \
  X(seeker_approach, "m/s, seekers' mean horizontal speed towards their nearest hider, seeking phase")      \
  X(ramp_wall_dist, "m, closest a ramp came to an interior wall in the seeking phase (6: no such wall)")    \
  X(seeker_high_seen, "1 if a seeker standing higher than an interior wall saw a hider")                    \
  X(seeker_high, "1 if a seeker stood higher than an interior wall in the seeking phase")                   \
  X(ramp_in_room_prep, "1 if a ramp's centre was inside the quadrant room at the end of prep")              \
  X(num_door_blocked_prep, "doors covered by boxes, locked or not, at the end of the preparation phase")    \
  X(hiders_in_room_prep, "fraction of the hiders inside the quadrant room at the end of prep")              \
  X(hiders_screened_prep, "fraction of the hiders beside a locked box at the end of prep (hider_screened)") \
  X(box_surf, "1 if a seeker rode a sliding box for kSurfSteps steps or more (box surfing)")                \
  X(max_agent_move, "m, largest agent displacement from its spawn at the end of the episode")               \
  X(food_eaten, "food units the hiders ate in the episode (the food variants)")

// Statistics of one finished episode, reported by the step that ended it.
struct EpisodeStats {
  int env = 0;
  int episode = 0;
  int length = 0;          // env steps
  bool discarded = false;  // ended early by numerical trouble
  float hider_return = 0;  // summed mean hider reward
  float seeker_return = 0;
#define HNS_DECLARE_EPISODE_STAT(name, doc) float name = 0;
  HNS_EPISODE_STATS(HNS_DECLARE_EPISODE_STAT)
#undef HNS_DECLARE_EPISODE_STAT
};

// Seconds of thread time spent per phase since the last reset_timers(), summed over envs.
struct PhaseTimes {
  double physics = 0;       // World::step (grab, lock, substeps)
  double mirror = 0;        // bodies read back from ODE into the SoA fields, ray-cast shapes
  double perception = 0;    // vision (cone + line of sight) and lidar
  double observations = 0;  // observation tensors
  double rewards = 0;       // rewards, statistics, auto-resets
  double total() const { return physics + mirror + perception + observations + rewards; }
};

// One phase of one env's step, for profiles (Chrome trace viewer). Times in ns since the BatchSim was built.
struct TraceEvent {
  const char* phase;  // "physics", "mirror", "vision+lidar", "rewards+resets", "observations"
  int64_t begin_ns;
  int64_t end_ns;
  int thread;  // TBB thread index within the arena
  int env;
};

class BatchSim {
 public:
  explicit BatchSim(const BatchConfig& config);
  ~BatchSim();
  BatchSim(const BatchSim&) = delete;
  BatchSim& operator=(const BatchSim&) = delete;

  // Starts episode 0 of every env.
  void reset();
  // Starts episode episodes[e] of every env e (a trainer resuming from a checkpoint). Size: num_envs.
  void reset(std::span<const int32_t> episodes);
  // Draws the episodes started from now on from `seed` instead of the config's (the next reset's scenes).
  void reseed(uint64_t seed);
  // Restarts env `env` on a given scene (tests, replays); the env's episode counter is kept.
  void load_scene(int env, const physics::Scene& scene);
  // One env step of every env, in parallel. actions: num_envs x max_agents (padding slots ignored).
  void step(std::span<const AgentAction> actions);
  // The same work for envs [begin, end), on the calling thread.
  void step_range(std::span<const AgentAction> actions, int begin, int end);

  const BatchConfig& config() const { return config_; }
  const Layout& layout() const { return layout_; }
  int num_envs() const { return config_.num_envs; }
  // The arena step() and reset() run in (config.threads slots): callers that alternate their own parallel
  // work with steps run it here too, so that the worker threads stay in one arena.
  tbb::task_arena& arena() { return *arena_; }
  const BatchState& state() const { return state_; }
  // Episodes that ended in the last step(), in env order.
  std::span<const EpisodeStats> finished() const { return finished_; }
  // Final observations (Gymnasium's): from now on, for every env whose episode ends in a step (and is not
  // discarded for numerical trouble), the named BatchState fields are observed once more and kept as they
  // were after the episode's last step, before the env starts its next episode in the same step. Costs one
  // observation pass and one copy per ended episode; nothing while no episode ends. Throws
  // std::invalid_argument for a name that is not a field.
  void keep_final(std::span<const std::string> fields);
  // The kept copy of field `name` (the field's layout and size), and per env 1 where its episode ended in
  // the last step (the copy holds that episode's last observation) and 0 elsewhere (stale).
  const uint8_t* final_field(const std::string& name) const;
  std::span<const uint8_t> final_mask() const { return final_mask_; }
  // Episodes reset after numerical trouble since construction.
  int64_t unstable_resets() const;
  const PhaseTimes& phase_times() const { return phase_times_; }
  void reset_timers() { phase_times_ = {}; }
  // While on, every step records one TraceEvent per env and phase (allocates: for short profiled runs).
  void set_tracing(bool on);
  // The events recorded since the last call, in env order.
  std::vector<TraceEvent> take_trace();
  // The time origin of TraceEvent times (when the BatchSim was built).
  std::chrono::steady_clock::time_point trace_epoch() const { return epoch_; }
  // Env e's occluders as the ray kernel sees them (walls, boxes, ramps, agents).
  ShapesView shapes(int env) const;
  // One phase of env e recomputed from its current SoA mirror, exactly as step() runs it after physics; the
  // benchmarks time the kernels this way. Vision: cone + line of sight (vis_* and the world's object
  // visibility); lidar; observations: the observation tensors and masks.
  void compute_vision(int env);
  void compute_lidar(int env);
  void compute_observations(int env);
  // The underlying world of env e (read-only; tests and tools).
  const physics::World& world(int env) const { return *worlds_[env]; }
  // Mutable access for tests and tools that stage a situation; the SoA mirror catches up at the next step,
  // or at once with resync().
  physics::World& mutable_world(int env) { return *worlds_[env]; }
  // Re-reads env e's bodies from its world and recomputes vision, lidar and observations exactly as a step
  // does after physics (rewards, statistics and counters are left alone).
  void resync(int env);
  // Shelter (docs/game.md §9.3): how many of the 100 rays from the arena's edges first hit env e's cylinder
  // now (0 without one); the step's reward is -0.001 per ray.
  int shelter_rays_reaching(int env) const;

 private:
  struct EnvScratch;
  EnvRef env_ref(int env);  // env `env` as the stages see it (env.hpp)
  void reset_env(int env, uint64_t episode);
  void start_episode_env(int env, uint64_t episode);  // after the world was reset: mirror, shapes, stats
  void refresh_env(int env);                          // mirror, shapes, vision, lidar
  void end_episode_env(int env, bool discarded);      // records the episode's statistics, starts the next
  void collect_finished();

  BatchConfig config_;
  Layout layout_;
  const Task* task_ = nullptr;  // the rules of the game the batch plays (tasks/task.hpp)
  BatchState state_;
  std::vector<std::unique_ptr<physics::World>> worlds_;
  std::vector<EnvScratch> scratch_;  // per env: finished-episode record, timers, counters
  std::vector<EpisodeStats> finished_;
  struct FinalField {
    std::string name;
    const uint8_t* source;  // the BatchState field
    size_t env_bytes;       // one env's share
    std::vector<uint8_t> copy;
  };
  std::vector<FinalField> final_;  // keep_final's fields
  std::vector<uint8_t> final_mask_;
  PhaseTimes phase_times_;
  bool tracing_ = false;
  std::unique_ptr<tbb::task_arena> arena_;  // config.threads workers, reused by every step
  std::chrono::steady_clock::time_point epoch_;
};

}  // namespace hns::batch
