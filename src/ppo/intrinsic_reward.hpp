// The exploration bonus added to the game's reward (config key `intrinsic`), behind one interface: `none`,
// `count` (count-based exploration, ppo/intrinsic.hpp) and `rnd` (random network distillation,
// ppo/rnd.hpp). The trainer makes one from its config (make_intrinsic_reward) and calls its hooks without
// knowing which runs; each writes and reads its own section of a checkpoint.
//
// A new kind is one class here and one line in make_intrinsic_reward / read_intrinsic_state (both refuse a
// name they do not know), and its name in the config's list of allowed values.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "batch/batch_sim.hpp"
#include "nn/actor_critic.hpp"
#include "ppo/checkpoint_io.hpp"
#include "ppo/train_config.hpp"

namespace hns::ppo {

// What a bonus computed after the rollout reads and writes of it: T steps of G rows (an env's A agent slots
// side by side), row t * G + g.
struct RolloutRewards {
  int steps = 0;                  // T
  int rows = 0;                   // G
  int agents = 0;                 // A: agent slots per env
  int minibatches = 0;            // the run's minibatch count (a learned bonus may step as often)
  const uint8_t* mask = nullptr;  // [T * G] 1 where the row is learned from
  const uint8_t* last = nullptr;  // [T * G] 1 on an episode's (or the rollout's) last step
  float* reward = nullptr;        // [T * G] the reward trained on: the bonus is added here
  nn::ObsBatch obs;               // the rollout's observations, row for row
  // Adds `bonus` to the episode return of local env e (the mean over its real agents, for the metrics).
  std::function<void(int env, double bonus)> add_to_episode;
};

// A checkpoint's bonus state, read and checked before any of it is applied.
class IntrinsicState {
 public:
  virtual ~IntrinsicState() = default;
  // Refuses values no run can produce: refuse(what) throws with the reason.
  virtual void check(const std::function<void(const std::string&)>& refuse) const = 0;
};

class IntrinsicReward {
 public:
  virtual ~IntrinsicReward() = default;
  // The config value that chose it: "none", "count", "rnd".
  virtual const char* name() const = 0;
  // After each simulator step: the bonus of the state that env `env` of s (the run's env `run_env`) reached,
  // given to each of its agents. The trainer does not call it for an env whose completed task holds it still.
  virtual float step_bonus(const batch::BatchState& s, const batch::Layout& layout, int env, int run_env) = 0;
  // True when it works on the whole rollout (after_rollout), timed as the iteration's t_intrinsic.
  virtual bool after_rollout_runs() const = 0;
  // After the rollout: adds bonuses to r.reward (and to the episodes' returns) and learns from the rollout.
  virtual void after_rollout(const RolloutRewards& r) = 0;
  // Its section of a checkpoint (nothing for none), after the normalisers.
  virtual void save(CheckpointWriter& w) const = 0;
  // Takes a state read by read_intrinsic_state for this kind and config (a resumed run).
  virtual void restore(const IntrinsicState& state) = 0;
};

// The bonus the config names (cfg.intrinsic), for a run of `ranks` processes whose networks are `net`.
// Throws physics::ConfigError for an unknown name, or count / rnd with more than one rank (their state is per
// env, or learned from one rollout, and saved whole with the checkpoint).
std::unique_ptr<IntrinsicReward> make_intrinsic_reward(const TrainConfig& cfg, const nn::NetConfig& net,
                                                       int ranks);

// Reads the checkpoint section of a run whose config is `saved` and networks `saved_net` (its intrinsic key
// says which section follows); std::runtime_error (the reader's, naming the file) if it does not fit.
std::unique_ptr<IntrinsicState> read_intrinsic_state(CheckpointReader& r, const TrainConfig& saved,
                                                     const nn::NetConfig& saved_net);

}  // namespace hns::ppo
