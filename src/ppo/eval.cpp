#include "ppo/eval.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "batch/batch_sim.hpp"
#include "batch/host.hpp"
#include "physics/rng.hpp"

namespace hns::ppo {

double random_policy_return(const TrainConfig& cfg, int episodes) {
  cfg.validate();
  if (episodes < 1 || episodes > 1000000) {
    throw physics::ConfigError("random-policy episodes = " + std::to_string(episodes) +
                               " is invalid: must be in [1, 1000000]");
  }
  batch::BatchConfig bc = cfg.batch_config();
  bc.num_envs = std::min(cfg.envs, episodes);
  bc.threads = batch::usable_threads(cfg.threads);
  bc.seed = cfg.seed;
  batch::BatchSim sim(bc);
  sim.reset();
  const int slots = sim.layout().max_agents;
  std::vector<physics::AgentAction> actions(size_t(bc.num_envs) * slots);
  physics::Rng rng(cfg.seed, 0x7A4D0A11ULL, 0);  // its own stream, apart from the worlds'
  double sum = 0;
  int counted = 0;
  while (counted < episodes) {
    for (physics::AgentAction& a : actions) a = physics::random_action(rng);
    sim.step(actions);
    for (const batch::EpisodeStats& e : sim.finished()) {
      if (counted == episodes) break;
      if (e.discarded) continue;
      sum += e.hider_return;
      ++counted;
    }
  }
  return sum / episodes;
}

namespace {
// t(0.95, df) for df = 1 .. 30: the two-sided 90 % quantile of Student's t.
constexpr double kT95[30] = {6.314, 2.920, 2.353, 2.132, 2.015, 1.943, 1.895, 1.860, 1.833, 1.812,
                             1.796, 1.782, 1.771, 1.761, 1.753, 1.746, 1.740, 1.734, 1.729, 1.725,
                             1.721, 1.717, 1.714, 1.711, 1.708, 1.706, 1.703, 1.701, 1.699, 1.697};
}  // namespace

MeanInterval mean_interval90(std::span<const double> values) {
  MeanInterval r;
  r.n = int(values.size());
  if (r.n == 0) return r;
  for (double v : values) r.mean += v;
  r.mean /= r.n;
  r.lo = r.hi = r.mean;
  if (r.n == 1) return r;
  double ss = 0;
  for (double v : values) ss += (v - r.mean) * (v - r.mean);
  const int df = r.n - 1;
  // Beyond the table t falls from 1.697 towards the normal's 1.645 roughly as 1/df.
  const double t = df <= 30 ? kT95[df - 1] : 1.645 + (kT95[29] - 1.645) * 30.0 / df;
  const double half = t * std::sqrt(ss / df / r.n);
  r.lo = r.mean - half;
  r.hi = r.mean + half;
  return r;
}

double normalised(double value, double random, double best) {
  const double span = best - random;
  return std::abs(span) < 1e-12 ? 0.0 : (value - random) / span;
}

}  // namespace hns::ppo
