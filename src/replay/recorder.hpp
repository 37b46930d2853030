// Records whole episodes of a BatchSim into TrajectoryEpisodes for the replay viewer.
//
// The batch auto-resets an env in the step that ends its episode, so the final state (after step `horizon`)
// would be overwritten before anyone could read it. The recorder therefore runs the batch with a horizon one
// step longer than the game's and the same number of preparation steps: steps 1..horizon are exactly the
// game's (the horizon only decides when an episode ends), frames 0..horizon are read from the batch state,
// and the extra step that follows only triggers the auto-reset into the env's next episode; it is not
// recorded.
//
//   per env: reset -> frame 0 -> step t (actions) -> frame t ... frame horizon -> extra step (reset) -> next
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "batch/batch_sim.hpp"
#include "physics/rng.hpp"
#include "replay/trajectory.hpp"

namespace hns::replay {

// Chooses the next step's actions of every env (num_envs x max_agents; padding slots are ignored).
using ActionFn = std::function<void(const batch::BatchSim&, std::span<physics::AgentAction>)>;

// Uniformly random actions (movement bins 0..10, grab and lock bits) from a stream per (seed, env, episode):
// an episode's actions depend on nothing else (thread count, other envs, env count).
class RandomActions {
 public:
  explicit RandomActions(uint64_t seed) : seed_(seed) {}
  void operator()(const batch::BatchSim& sim, std::span<physics::AgentAction> actions);

 private:
  uint64_t seed_;
  std::vector<physics::Rng> streams_;
  std::vector<int> stream_episode_;
};

struct RecordConfig {
  batch::BatchConfig game;  // the game as played (its horizon, seed, envs, threads)
  std::string scene;        // preset name written to the headers
  int episodes = 1;         // whole episodes to record
};

struct RecordSummary {
  int recorded = 0;
  int discarded = 0;  // episodes cut short by numerical trouble (the batch reset the env); not recorded
};

// The batch configuration a recording runs: the game's, with the horizon one longer and the preparation
// phase unchanged. Throws physics::ConfigError if the game's config is invalid.
batch::BatchConfig recording_batch_config(const batch::BatchConfig& game);

// Plays until `episodes` whole episodes are recorded and hands each to `sink` as it completes (env order
// within a step). Deterministic for a given config and deterministic actions, whatever the thread count.
RecordSummary record_episodes(const RecordConfig& config, const ActionFn& actions,
                              const std::function<void(const TrajectoryEpisode&)>& sink);

// The env's present state as a one-frame episode (header and frame 0: poses, locks, perception, the last
// step's rewards, whether the env is in its preparation phase), for a picture of it (render.hpp).
TrajectoryEpisode snapshot(const batch::BatchSim& sim, int env, const std::string& scene);

}  // namespace hns::replay
