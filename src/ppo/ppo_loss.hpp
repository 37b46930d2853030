// The trainer's minibatch loss, chunk by chunk (docs/game.md §10.4, paper appendix B): the clipped surrogate
// on the summed log-probability of the five action heads, plus value_coef times the value loss (normalised
// targets), minus entropy_coef times the entropy, each a mean over the minibatch's real agent-steps. It is an
// nn::LossFn body: ActorCritic::forward_backward calls it once per chunk, and it writes the gradient of the
// minibatch loss w.r.t. that chunk's logits and value outputs.
#pragma once

#include "nn/actor_critic.hpp"

#include <cstdint>
#include <span>
#include <vector>

namespace hns::ppo {

// Loss statistics summed over chunks: policy loss, value loss (each x count), entropy (summed), approx KL x
// count, clipped entries, count (real agent-steps).
enum PpoStat { kPolicyLoss, kValueLoss, kEntropy, kKl, kClipped, kCount, kNumPpoStats };

// One minibatch, rows sequence-major (the rows ChunkOutputs::first_row indexes).
struct PpoMinibatch {
  const int32_t* actions = nullptr;   // [rows, heads] taken in the rollout
  const float* old_logp = nullptr;    // [rows] their log-probability in the rollout
  const float* advantages = nullptr;  // [rows] z-scored
  const float* returns = nullptr;     // [rows] value targets, normalised
  const uint8_t* mask = nullptr;      // [rows] 1 for real agent-steps, 0 for padding
  float clip = 0.2f;
  double entropy_coef = 0.01;
  double value_coef = 0.5;
  double inv_total = 0.0;  // 1 / (real agent-steps of the whole minibatch)
};

// Per-thread scratch (grows to the largest chunk; no allocation once it has).
struct PpoLossScratch {
  std::vector<float> new_logp, entropy, grad_logp, d_entropy, grad_value;
  std::vector<double> heads_saved;  // the heads' softmaxes, from the loss to its gradient
};

// One chunk: reads out's logits and values, writes g (d loss / d logits, d loss / d value) and adds the
// chunk's share to stats [kNumPpoStats].
void ppo_chunk_loss(const nn::CategoricalHeads& heads, const PpoMinibatch& mb, const nn::ChunkOutputs& out,
                    const nn::ChunkGrads& g, PpoLossScratch& scratch, std::span<double> stats);

// The minibatch loss from its summed statistics (the quantity whose gradient ppo_chunk_loss writes).
double ppo_total_loss(std::span<const double> stats, const PpoMinibatch& mb);

}  // namespace hns::ppo
