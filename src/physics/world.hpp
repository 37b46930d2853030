// One hide-and-seek world on ODE (docs/game.md §1-§3, §14): bodies, walls, movement, grab, lock, the
// preparation phase and substepping. Rewards, observations and statistics live in the batch layer.
//
// Per env step (World::step):
//   actions -> seekers zeroed in prep -> grab (closest visible object in range) -> lock/unlock (team rule)
//   -> forces -> substeps {collide, QuickStep, implicit damping, keep yaw-only} -> visibility for next step
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "physics/geometry.hpp"
#include "physics/rng.hpp"
#include "physics/scene.hpp"

namespace hns::physics {

// Solver and integration settings. The defaults reproduce the motion profile of docs/game.md §14.4.
struct PhysicsConfig {
  double step_time = 0.075;              // s of simulated time per env step (docs/game.md §1.1)
  int substeps = 10;                     // ODE steps per env step (7.5 ms each: 6 cm at top speed)
  int solver_iterations = 10;            // QuickStep iterations per substep
  double gravity = -50.0;                // m/s² along z
  double erp = 0.2;                      // error reduction for joints and contacts
  double cfm = 1e-5;                     // constraint force mixing
  double contact_surface_layer = 0.001;  // m of allowed penetration, steadies resting contacts
  double max_correcting_vel = 5.0;       // m/s, cap on contact depenetration speed
  // Contacts with the floor are soft by this constraint force mixing (ODE's CFM), so that a box's or ramp's
  // weight spreads over its bottom corners as MuJoCo's soft contacts spread it (docs/physics.md); 0: rigid.
  double floor_cfm = 1.3e-3;
  // A contact sliding faster than this (m/s) has its friction along the slip and none across it; slower
  // ones keep ODE's fixed friction pyramid (static friction both ways). 0: the fixed pyramid always.
  double slip_speed = 0.1;
  // Boxes and ramps slower than these for sleep_substeps substeps leave the solver until touched.
  bool sleep = true;
  double sleep_linear_speed = 0.02;   // m/s
  double sleep_angular_speed = 0.05;  // rad/s
  int sleep_substeps = 5;
};

// Everything a world needs. The scenes (batch::kScenes, batch/scenes.hpp) set it beside the rules only the
// batch reads (batch::GameRules: the game, the out-of-bounds rectangle, the food).
struct WorldConfig {
  SceneConfig scene = SceneConfig::quadrant();
  PhysicsConfig physics;
  int horizon = 80;                  // env steps per episode
  double prep_fraction = 0.4;        // first ceil(prep_fraction * horizon) steps are preparation
  bool lock_ramps = false;           // ramps lockable (full game) or not (quadrant)
  double grab_radius = 0.25;         // m, agent centre to object cuboid (docs/game.md §3.3)
  double grab_release_slack = 0.05;  // m, a held object is released beyond grab_radius + slack (§14.2)
  double lock_radius = 0.25;         // m (docs/game.md §3.4)
  bool compute_visibility = true;    // fill the agent-object visibility after reset and each step
  // Locks of boxes after the first unlocked one (in index order) are refused (the sequential-lock task,
  // docs/game.md §9.2).
  bool lock_in_order = false;

  // The worlds of the hide-and-seek game's scenes (docs/game.md §2.1), for what steps worlds without a batch
  // (the physics tests and benchmarks, the MuJoCo parity tool) and as the scenes' starting points; the
  // scenes (batch/scenes.hpp) add the rules. quadrant: the room with doors, horizon 80; full: random rooms,
  // lockable ramps, horizon 240; empty: the arena without inner walls, lockable ramps, horizon 80.
  static WorldConfig quadrant();
  static WorldConfig full();
  static WorldConfig empty();
  // Throws ConfigError naming the first bad field (the scene's fields included).
  void validate() const;
  int prep_steps() const;
  int max_agents() const { return scene.hiders.max + scene.seekers.max; }
};

// Throws ConfigError "field = value is invalid: allowed" unless `ok`, the value in the shortest form that
// reads back as it (1000001 and 0.1, not 1e+06 or 0.10000000000000001).
void check_field(bool ok, std::string_view field, double value, std::string_view allowed);

enum class Team : uint8_t { kHider = 0, kSeeker = 1 };

// One agent's action: movement bins 0..10 (5 = zero) for force x, force y (world frame) and torque z;
// grab and lock bits (docs/game.md §3).
struct AgentAction {
  uint8_t move_x = 5;
  uint8_t move_y = 5;
  uint8_t turn = 5;
  uint8_t grab = 0;
  uint8_t lock = 0;
};

inline constexpr int kMoveBins = 11;

// A uniformly random action: every movement bin, grab and lock bit equally likely (drawn in that order).
template <class Rng>
AgentAction random_action(Rng& rng) {
  AgentAction a;
  a.move_x = uint8_t(rng.uniform_int(0, kMoveBins));
  a.move_y = uint8_t(rng.uniform_int(0, kMoveBins));
  a.turn = uint8_t(rng.uniform_int(0, kMoveBins));
  a.grab = uint8_t(rng.uniform_int(0, 2));
  a.lock = uint8_t(rng.uniform_int(0, 2));
  return a;
}
inline constexpr double kMaxControl = 0.9;  // bin 0 = -0.9, bin 10 = +0.9
inline constexpr double kGear = 100.0;      // N (or N·m) per unit of control
// Control value of a movement bin: linspace(-0.9, 0.9, 11).
inline double bin_control(int bin) {
  return -kMaxControl + 2.0 * kMaxControl * bin / (kMoveBins - 1);
}

// Pose and velocity of one body, true centre (docs/game.md §14.1).
struct BodyState {
  double pos[3];   // m
  double cos_yaw;  // yaw as (cos, sin), read from the body's quaternion without trigonometry
  double sin_yaw;
  double vel[3];   // m/s
  double ang_vel;  // rad/s about z

  // Yaw angle, rad, in [-pi, pi].
  double yaw() const { return std::atan2(sin_yaw, cos_yaw); }
};

class World {
 public:
  // Validates the config (ConfigError) and allocates bodies for the configured maxima. Call reset() next.
  World(const WorldConfig& config, uint64_t seed, uint64_t world_index);
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  // Starts episode `episode` with a scene drawn from the stream (seed, world index, episode).
  void reset(uint64_t episode);
  // Starts the next episode (episode() + 1).
  void reset() { reset(episode_ + 1); }
  // Episodes started from now on are drawn from the stream (seed, world index, episode).
  void set_seed(uint64_t seed) { seed_ = seed; }
  // Starts an episode on a given scene (tests, replays). Counts must fit the configured maxima.
  void reset_with_scene(const Scene& scene, uint64_t episode = 0);

  // Advances one env step. actions.size() must equal num_agents().
  void step(std::span<const AgentAction> actions);

  // Episode state.
  uint64_t episode() const { return episode_; }
  int step_count() const { return t_; }                    // env steps taken this episode
  bool in_prep_phase() const { return t_ < prep_steps_; }  // the next step is a preparation step
  bool done() const { return t_ >= config_.horizon; }
  bool unstable() const { return unstable_; }  // a body left the sane range or went non-finite
  const Scene& scene() const { return scene_; }
  const WorldConfig& config() const { return config_; }

  int num_agents() const { return scene_.num_hiders + scene_.num_seekers; }
  int num_hiders() const { return scene_.num_hiders; }
  int num_seekers() const { return scene_.num_seekers; }
  int num_boxes() const { return int(scene_.boxes.size()); }
  int num_ramps() const { return int(scene_.ramps.size()); }
  int num_objects() const { return num_boxes() + num_ramps(); }  // object o: boxes first, then ramps
  Team team(int agent) const { return agent < scene_.num_hiders ? Team::kHider : Team::kSeeker; }

  BodyState agent_state(int agent) const;
  BodyState box_state(int box) const;
  BodyState ramp_state(int ramp) const;  // position of the ramp's bounding-box centre
  bool object_locked(int object) const { return locked_[object] != 0; }
  // Team that locked the object last (-1: never locked).
  int object_lock_team(int object) const { return lock_team_[object]; }
  // Agent that locked the object last (-1: never locked).
  int object_locker(int object) const { return locker_[object]; }
  // Object the agent holds (-1: none).
  int agent_holding(int agent) const { return holding_[agent]; }

  // Agent-object visibility used by the next step's grab and lock (num_agents x num_objects, 1 = seen).
  // Filled by update_visibility() when config.compute_visibility; the batch layer may write it instead.
  std::span<uint8_t> object_visibility() {
    return {visibility_.data(), size_t(num_agents() * num_objects())};
  }
  std::span<const uint8_t> object_visibility() const {
    return {visibility_.data(), size_t(num_agents() * num_objects())};
  }
  void update_visibility();

  // The current geometry as occluders for the scalar vision and lidar routines (agents with their arms).
  Occluders occluders();

  // Test and tooling hooks: move a body (velocities are zeroed).
  void set_agent_pose(int agent, double x, double y, double z, double yaw);
  void set_box_pose(int box, double x, double y, double z, double yaw);
  void set_ramp_pose(int ramp, double x, double y, double z, double yaw);

  struct Ode;  // ODE handles, defined in world.cpp only

 private:
  void build_scene();
  void apply_grab(std::span<const AgentAction> actions);
  void apply_lock(std::span<const AgentAction> actions);
  void set_locked(int object, bool locked);
  void release(int agent);
  double agent_object_distance(int agent, int object) const;
  void substep(std::span<const double> forces);
  void check_stability();

  WorldConfig config_;
  uint64_t seed_;
  uint64_t world_index_;
  uint64_t episode_ = 0;
  Rng rng_;
  Scene scene_;
  int t_ = 0;
  int prep_steps_ = 0;
  bool unstable_ = false;
  std::unique_ptr<Ode> ode_;

  // Per-object state (boxes then ramps), sized for the maxima.
  std::vector<uint8_t> locked_;    // 1 = pinned
  std::vector<int8_t> lock_team_;  // team of the last locker, -1 = never locked
  std::vector<int8_t> locker_;     // agent that locked last, -1 = never
  // Per-agent state.
  std::vector<int> holding_;         // object held, -1 = none
  std::vector<uint8_t> visibility_;  // agent x object
  std::vector<double> forces_;       // agent x 3: force x, force y (N), torque z (N·m)
  std::vector<uint8_t> scratch_;     // per-agent/object flags used inside step
  // Occluder scratch (refreshed by occluders()).
  std::vector<OrientedBox> occ_walls_, occ_boxes_;
  std::vector<Wedge> occ_ramps_;
  std::vector<Sphere> occ_agents_, occ_arms_;
  std::vector<Cylinder> occ_cylinders_;
};

}  // namespace hns::physics
