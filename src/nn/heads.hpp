// Categorical action heads (docs/game.md §10.2 _init_policy_out): the policy's logits row is split into
// independent categoricals (hide-and-seek: 3 x 11 movement bins, 2 grab, 2 lock = 37 logits, 5 actions per
// agent). Log-probabilities and entropies are summed over the heads. Sampling takes one caller-provided
// uniform number in [0, 1) per head and inverts the CDF, so it is deterministic given the caller's random
// stream.
#pragma once

#include "nn/tensor.hpp"

#include <cstdint>
#include <vector>

namespace hns::nn {

class CategoricalHeads {
 public:
  static constexpr int kMaxChoices = 64;  // per head (scratch lives on the stack)

  CategoricalHeads() = default;
  // One entry per categorical: its number of choices.
  explicit CategoricalHeads(std::vector<int> sizes);

  int num_heads() const { return static_cast<int>(sizes_.size()); }
  int num_logits() const { return num_logits_; }
  const std::vector<int>& sizes() const { return sizes_; }

  // logits [rows, num_logits]; actions [rows, num_heads]; logp, entropy [rows] (either may be null). With
  // saved [rows, saved_doubles(1)] (may be null): what backward needs of each row (log-probabilities,
  // probabilities, the heads' entropies), for backward_saved.
  void log_prob_entropy(CMat logits, const int32_t* actions, float* logp, float* entropy,
                        double* saved = nullptr) const;
  size_t saved_doubles(int rows) const { return size_t(rows) * size_t(2 * num_logits_ + num_heads()); }
  // uniforms [rows, num_heads] in [0, 1); writes actions and (if not null) their summed log-probability.
  void sample(CMat logits, const float* uniforms, int32_t* actions, float* logp) const;
  // Most likely action of each head (ties: the lowest index).
  void argmax(CMat logits, int32_t* actions) const;
  // d_logits = d_logp * dlogp/dlogits + d_entropy * dentropy/dlogits (written); either input may be null.
  void backward(CMat logits, const int32_t* actions, const float* d_logp, const float* d_entropy,
                Mat d_logits) const;
  // The same from log_prob_entropy's saved values of the same logits and rows, with the same bits (without
  // computing the softmaxes and their exponentials again).
  void backward_saved(const double* saved, int rows, const int32_t* actions, const float* d_logp,
                      const float* d_entropy, Mat d_logits) const;

 private:
  std::vector<int> sizes_;
  std::vector<int> offsets_;
  int num_logits_ = 0;
  int max_size_ = 0;
};

}  // namespace hns::nn
