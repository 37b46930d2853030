// Acting with a trained policy outside training: recordings (`hns play --checkpoint`), replays of a running
// training, evaluation. Samples every agent's actions from the policy heads like the rollout does, with the
// LSTM state carried per agent slot and zeroed when its env is at the first step of an episode. The uniforms
// come from a stream per (seed, env, episode), so an episode's actions depend on nothing else.
#pragma once

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "batch/batch_sim.hpp"
#include "physics/rng.hpp"
#include "ppo/batch_obs.hpp"
#include "ppo/trainer.hpp"

namespace hns::ppo {

class Policy {
 public:
  // Acts with a trainer's current networks (the trainer must outlive the policy and not train meanwhile).
  Policy(const Trainer& trainer, uint64_t seed);
  // Loads the networks of a checkpoint (std::runtime_error naming the problem for a bad file). They act at
  // the run's precision where this CPU has it: a bf16 run acts in fp32 on a CPU without bf16.
  static std::unique_ptr<Policy> from_checkpoint(const std::string& path, uint64_t seed);
  ~Policy();

  // The config of the run the networks come from (its scene and model).
  const TrainConfig& config() const { return trainer_->config(); }
  // The observation shape the networks were trained on (max agents, boxes, ramps of the scene).
  const nn::ObsShape& obs_shape() const;
  // LSTM state floats per agent slot and network: (c, h).
  int state_width() const;
  // Fills actions (num_envs x max_agents) for the batch's current observations, with the LSTM states kept
  // here. The batch's layout must be the one the networks were trained on (same scene).
  void act(const batch::BatchSim& sim, std::span<physics::AgentAction> actions);
  // The same for `envs` envs of observations held anywhere (obs_shape()'s layout), with the caller's LSTM
  // states: policy_state and value_state [envs x max_agents, state_width()] are read and replaced (zeroed
  // first for the envs whose step_count is 0). Draws the same uniforms as act(sim), so a caller that steps
  // its own batch with these actions plays the same episodes as `hns play --checkpoint`. The sampling stream
  // of env e is kept per env index (and restarted at each new episode number): two batches acted for by one
  // Policy share the streams of their common env indices.
  void act(const StepObsView& obs, int envs, float* policy_state, float* value_state,
           std::span<physics::AgentAction> actions);

 private:
  Policy(std::unique_ptr<Trainer> owned, uint64_t seed);
  void resize(int envs);

  std::unique_ptr<Trainer> owned_;
  const Trainer* trainer_;
  uint64_t seed_;
  int rows_ = 0;  // agent rows the buffers below are sized for
  nn::ObsStore obs_;
  nn::FloatBuffer state_p_, state_v_, uniforms_;
  std::vector<int32_t> actions_;
  std::vector<physics::Rng> streams_;
  std::vector<int> stream_episode_;
};

}  // namespace hns::ppo
