// The object-counting probe: the head reads a count that the states hold and only the majority class from
// states that hold none; states and labels come from frozen-policy episodes, the same bits on any thread
// count.
#include "ppo/counting.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <vector>

#include "physics/rng.hpp"

namespace hns::ppo {
namespace {

// Labels drawn like the task's (6 fair coin flips); states of `units` floats around a fixed pattern, with the
// label written into the first two features (or not at all) and some noise.
void synthetic(int n, int units, bool informative, uint64_t seed, std::vector<float>& x,
               std::vector<int32_t>& y) {
  physics::Rng rng(seed, 1, 2);
  x.assign(size_t(n) * units, 0.0f);
  y.assign(size_t(n), 0);
  for (int i = 0; i < n; ++i) {
    int left = 0;
    for (int k = 0; k < 6; ++k) left += rng.bernoulli(0.5) ? 1 : 0;
    y[size_t(i)] = left;
    for (int u = 0; u < units; ++u)
      x[size_t(i) * units + u] = float(0.3 * u - 1.0 + 0.05 * rng.uniform(-1, 1));
    if (informative) {
      x[size_t(i) * units] += 0.2f * float(left);
      x[size_t(i) * units + 1] -= 0.1f * float(left);
    }
  }
}

TEST(CountingProbe, TheHeadReadsACountTheStatesHoldAndOnlyTheMajorityOtherwise) {
  std::vector<float> xtr, xte;
  std::vector<int32_t> ytr, yte;
  CountingHeadConfig cfg;
  cfg.epochs = 300;
  synthetic(1024, 8, true, 1, xtr, ytr);
  synthetic(512, 8, true, 2, xte, yte);
  const CountingHeadResult good = train_counting_head(8, xtr, ytr, xte, yte, cfg);
  EXPECT_GT(good.test_accuracy, 0.9);
  EXPECT_GT(good.train_accuracy, 0.9);
  EXPECT_LT(good.majority_accuracy, 0.4);  // class 3 is 5/16 of the episodes
  synthetic(1024, 8, false, 1, xtr, ytr);
  synthetic(512, 8, false, 2, xte, yte);
  const CountingHeadResult blind = train_counting_head(8, xtr, ytr, xte, yte, cfg);
  EXPECT_LT(blind.test_accuracy, blind.majority_accuracy + 0.06);
}

TrainConfig counting_trainer_config() {
  TrainConfig c;
  c.scene = "object-counting";
  c.model = "small";
  c.envs = 1;
  c.threads = 1;
  c.seed = 4;
  return c;
}

TEST(CountingProbe, CollectsEachEpisodesFinalStateAndHowManyBoxesWentLeft) {
  Trainer trainer(counting_trainer_config());
  std::vector<float> one, two;
  std::vector<int32_t> labels_one, labels_two;
  collect_counting_states(trainer, 10, 20, 8, 1, one, labels_one);  // 3 rounds, the last one partial
  collect_counting_states(trainer, 10, 20, 8, 2, two, labels_two);
  const int units = trainer.net().state_width() / 2;
  ASSERT_EQ(one.size(), size_t(20) * units);
  EXPECT_EQ(0, std::memcmp(one.data(), two.data(), one.size() * sizeof(float)))
      << "thread count changed bits";
  EXPECT_EQ(labels_one, labels_two);
  // The labels are the scenes' sides: episode 10 + i of the run's seed.
  const physics::WorldConfig w = trainer.config().world();
  for (int i = 0; i < 20; ++i) {
    physics::Rng rng(trainer.config().seed, uint64_t(i % 8), uint64_t(10 + i));
    physics::Scene scene;
    physics::generate_scene(w.scene, rng, scene);
    EXPECT_EQ(labels_one[size_t(i)], std::count(scene.sides.begin(), scene.sides.end(), int8_t{-1})) << i;
  }
  // Different episodes leave different states (the boxes the policy saw differ).
  EXPECT_NE(0, std::memcmp(one.data(), one.data() + units, units * sizeof(float)));
  std::vector<float> other;
  std::vector<int32_t> other_labels;
  collect_counting_states(trainer, 30, 4, 4, 1, other, other_labels);
  EXPECT_NE(0, std::memcmp(one.data(), other.data(), units * sizeof(float)));
}

}  // namespace
}  // namespace hns::ppo
