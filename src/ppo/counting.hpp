// Object counting (the paper's §6 and appendix; docs/transfer.md "Object counting"): a probe of what a
// policy's memory holds. A frozen policy watches object-counting episodes (the `object-counting` scene: the
// agent pinned, 6 boxes sliding one by one to the left or the right, behind screens). Its LSTM output at the
// episode's last step is the representation; a classification head (layer norm, dense 64 + ReLU, dense 7) is
// trained on it with Adam to say how many of the 6 boxes went left (7 classes), and scored on held-out
// episodes. The paper's baseline is the same head on a frozen policy from the seed.
#pragma once

#include <cstdint>
#include <vector>

#include "ppo/trainer.hpp"

namespace hns::ppo {

inline constexpr int kCountingClasses = 7;  // 0 .. 6 boxes went left

// The final LSTM output (h) of agent 0 in `episodes` object-counting episodes (episode numbers first_episode
// .. first_episode + episodes - 1 of the run's seed) played by the trainer's policy, frozen, in batches of
// `envs` envs on `threads` threads (0: all): states [episodes, lstm units] and labels [episodes] (boxes
// that went left). The trainer's scene must be object-counting. Deterministic (any thread count).
void collect_counting_states(const Trainer& trainer, int64_t first_episode, int episodes, int envs,
                             int threads, std::vector<float>& states, std::vector<int32_t>& labels);

struct CountingHeadConfig {
  int hidden = 64;   // the paper's dense layer
  int epochs = 500;  // passes over the training episodes
  int batch = 128;   // episodes per Adam step
  double lr = 1e-3;
  uint64_t seed = 1;  // the head's initialisation and the shuffling
};

struct CountingHeadResult {
  double train_accuracy = 0, test_accuracy = 0;
  double train_loss = 0;         // mean cross-entropy of the last epoch
  double majority_accuracy = 0;  // test episodes of the training set's most frequent class: what ignoring the
                                 // state scores
};

// Trains the head on (train_states, train_labels) and scores it on the test set; `units` floats per state.
CountingHeadResult train_counting_head(int units, const std::vector<float>& train_states,
                                       const std::vector<int32_t>& train_labels,
                                       const std::vector<float>& test_states,
                                       const std::vector<int32_t>& test_labels,
                                       const CountingHeadConfig& config);

}  // namespace hns::ppo
