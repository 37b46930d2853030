// The pieces of the transfer suite (`hns eval`, docs/transfer.md) that are not a training run: the return of
// a uniformly random policy on a scene, and the statistics of curves over seeds (the mean with its 90 %
// interval, and normalised performance).
#pragma once

#include <span>

#include "ppo/train_config.hpp"

namespace hns::ppo {

// Mean hider return (agent 0's summed reward in a single-agent task) of the first `episodes` episodes to end
// when every agent acts uniformly at random (each movement bin, grab and lock bit equally likely), on
// cfg.world() with min(cfg.envs, episodes) envs seeded from cfg.seed and cfg.threads threads. The same number
// for any thread count. Throws physics::ConfigError for a bad config or episodes < 1.
double random_policy_return(const TrainConfig& cfg, int episodes);

// A mean over seeds with its two-sided 90 % confidence interval: mean ± t(0.95, n - 1) · s / √n (Student t;
// n = 1 gives lo = hi = mean).
struct MeanInterval {
  double mean = 0, lo = 0, hi = 0;
  int n = 0;
};
MeanInterval mean_interval90(std::span<const double> values);

// Normalised performance of a return (the paper's fine-tuning figure): (value - random) / (best - random),
// 0 at the random policy's return and 1 at the best condition's; 0 when best and random coincide.
double normalised(double value, double random, double best);

}  // namespace hns::ppo
