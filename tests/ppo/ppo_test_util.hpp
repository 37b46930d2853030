// Helpers shared by the PPO tests: tiny quadrant training configs, a trainer's parameters, per-process
// temporary file names and an iteration's metrics without the timings (which differ between runs that are
// otherwise bit-identical).
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "ppo/trainer.hpp"

namespace hns::ppo::testing {

// Two agents a side in the quadrant game, a few envs: small and quick, yet every part of the loop runs.
inline TrainConfig tiny_quadrant() {
  TrainConfig c;
  c.scene = "quadrant";
  c.model = "small";
  c.envs = 3;
  c.horizon = 20;
  c.epochs = 2;
  c.minibatches = 2;
  c.threads = 1;
  c.seed = 7;
  return c;
}

inline std::vector<float> params_of(const Trainer& t) {
  const float* p = t.net().params().values();
  return {p, p + t.net().params().buffer_floats()};
}

// Named by the process too: two test runs on one machine (two build trees, ctest -j) must not share files.
inline std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("hns_trainer_test_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

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
