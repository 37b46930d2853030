// Helpers shared by the PPO tests: a tiny quadrant training config and an iteration's metrics without the
// timings (which differ between runs that are otherwise bit-identical).
#pragma once

#include <string>

#include "ppo/trainer.hpp"

namespace hns::ppo::testing {

// Quadrant, small model, 2 envs of 20 steps, 1 epoch of 2 minibatches, one thread, seed 3.
inline TrainConfig tiny_intrinsic_config(const char* intrinsic) {
  TrainConfig c;
  c.scene = "quadrant";
  c.model = "small";
  c.envs = 2;
  c.horizon = 20;
  c.epochs = 1;
  c.minibatches = 2;
  c.threads = 1;
  c.seed = 3;
  c.intrinsic = intrinsic;
  return c;
}

inline std::string metrics_but_timings(const IterationMetrics& m) {
  IterationMetrics z = m;
  z.seconds = z.steps_per_s = z.t_simulate = z.t_observe = z.t_infer = z.t_learn = z.t_other = 0;
  z.t_targets = z.t_backward = z.t_optimizer = z.t_comm = z.t_intrinsic = 0;
  return z.to_json();
}

}  // namespace hns::ppo::testing
