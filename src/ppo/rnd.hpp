// Random network distillation (the paper's appendix "Intrinsic motivation"; Burda et al. 2018), the RND
// baseline of `--set intrinsic=rnd`. A target network, fixed at its random initialisation, and a predictor
// network that learns to reproduce the target's output on the observations the agents visit. Both have the
// value network's architecture (the omniscient masks) without its LSTM, with a linear 64-wide output
// (nn::NetHead::kRnd). The prediction error of an observation, the mean over the 64 outputs of the squared
// difference, is the intrinsic reward: observations like those already visited pay less.
//
// Determinism (docs/design.md "Determinism"): the rows are cut into chunks of kRndChunkRows and the chunks into kRndGroups
// contiguous groups, independently of the thread count. Each group sums its chunks' gradients in order and
// the groups are summed in order, so errors and training steps are bit-identical for any thread count.
#pragma once

#include "nn/actor_critic.hpp"
#include "nn/adam.hpp"

#include <oneapi/tbb/enumerable_thread_specific.h>

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

namespace hns::ppo {

inline constexpr int kRndChunkRows = 64;
inline constexpr int kRndGroups = 8;

class Rnd {
 public:
  // `base`: the run's network config (observation shape and widths); the RND networks drop its LSTM. The
  // target's weights come from `seed` (a stream of its own), the predictor's from another; the predictor
  // learns with Adam at `lr`.
  Rnd(const nn::NetConfig& base, uint64_t seed, float lr);
  ~Rnd();
  Rnd(const Rnd&) = delete;
  Rnd& operator=(const Rnd&) = delete;

  // Prediction error of `rows` rows of obs (read with `norm`, the value net's masks): out[r] = mean over the
  // 64 outputs of (predictor - target)^2.
  void errors(const nn::ObsNormView& norm, const nn::ObsBatch& obs, size_t rows, float* out) const;
  // One Adam step of the predictor on the mean prediction error over obs's rows `rows` (indices into the
  // arrays; obs.index must be null). Returns that mean error (before the step); rows empty: nothing, 0.
  double train(const nn::ObsNormView& norm, const nn::ObsBatch& obs, std::span<const int32_t> rows);

  nn::ParamStore& predictor() { return predictor_; }
  const nn::ParamStore& predictor() const { return predictor_; }
  const nn::ParamStore& target() const { return target_; }
  nn::Adam& optimizer() { return *adam_; }
  const nn::Adam& optimizer() const { return *adam_; }
  const nn::NetConfig& config() const { return cfg_; }
  // Floats of the predictor's parameter buffer for a run's network config (to read a checkpoint).
  static size_t predictor_floats(const nn::NetConfig& base);

 private:
  struct Work;
  Work& local_work() const;
  // Forward of both networks over `rows` rows of obs: the target's outputs copied into target_out [rows, 64],
  // the predictor's left in w.predictor.
  void forward_both(const nn::ObsNormView& norm, const nn::ObsBatch& obs, int rows, Work& w) const;

  nn::NetConfig cfg_;
  nn::EntityNet target_net_, predictor_net_;
  nn::ParamStore target_, predictor_;
  std::unique_ptr<nn::Adam> adam_;
  mutable tbb::enumerable_thread_specific<std::unique_ptr<Work>> work_;
  std::vector<nn::FloatBuffer> group_grads_;  // [kRndGroups][predictor floats]
};

}  // namespace hns::ppo
