// Observation normaliser: debiased EMA statistics, the std floor, and the float view the kernels read.
#include "nn/obs_normalizer.hpp"
#include "nn/entity_net.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

namespace hns::nn {
namespace {

// Two self features, one agent (no others), `boxes` boxes of one feature, no ramps, `rays` lidar rays.
ObsShape tiny_shape(int boxes, int rays) {
  ObsShape s;
  s.self_features = 2;
  s.max_agents = 1;
  s.max_boxes = boxes;
  s.box_features = 1;
  s.max_ramps = 0;
  s.lidar_rays = rays;
  return s;
}

TEST(NnObsNormalizer, DebiasedEmaAndFloor) {
  ObsNormalizer n(tiny_shape(1, 3), 0.9);
  // Identity before the first update.
  EXPECT_EQ(n.view().mean[kObsSelf][0], 0.0f);
  EXPECT_EQ(n.view().inv_std[kObsSelf][0], 1.0f);
  // Batch 1: self feature 0 in {1, 3}, feature 1 constant 5; lidar {0..5}.
  const std::vector<float> self1 = {1, 5, 3, 5}, lidar1 = {0, 1, 2, 3, 4, 5}, boxes1 = {2, 2};
  n.update(self1.data(), lidar1.data(), nullptr, boxes1.data(), nullptr, nullptr, 2);
  EXPECT_NEAR(n.mean(kObsSelf, 0), 2.0, 1e-12);  // debiased: exactly the batch mean after one update
  EXPECT_NEAR(n.std(kObsSelf, 0), 1.0, 1e-9);
  EXPECT_NEAR(n.std(kObsSelf, 1), 0.1, 1e-9);  // constant feature: the std floor sqrt(1e-2)
  EXPECT_NEAR(n.mean(kObsLidar, 0), 2.5, 1e-12);
  EXPECT_FLOAT_EQ(n.view().mean[kObsLidar][2], 2.5f);  // one channel shared by every ray
  // Batch 2: feature 0 constant 4. EMA with beta 0.9: weights 0.1 * 0.9 and 0.1, debias 0.19.
  const std::vector<float> self2 = {4, 5, 4, 5};
  n.update(self2.data(), nullptr, nullptr, nullptr, nullptr, nullptr, 2);
  const double mean = (0.09 * 2.0 + 0.1 * 4.0) / 0.19;
  const double sq = (0.09 * 5.0 + 0.1 * 16.0) / 0.19;
  EXPECT_NEAR(n.mean(kObsSelf, 0), mean, 1e-12);
  EXPECT_NEAR(n.std(kObsSelf, 0), std::sqrt(sq - mean * mean), 1e-9);
  EXPECT_FLOAT_EQ(n.view().inv_std[kObsSelf][0], static_cast<float>(1.0 / std::sqrt(sq - mean * mean)));
}

// The default beta is the original's 0.99999 (src/nn/README.md, docs/game.md): after batches with means 2 and
// 4 the debiased mean is (2 beta + 4) / (1 + beta), 2.999995 (0.9999 would give 3.00005).
TEST(NnObsNormalizer, DefaultBetaIsTheOriginals) {
  ObsNormalizer n(tiny_shape(1, 3));
  const std::vector<float> self1 = {2, 0, 2, 0}, self2 = {4, 0, 4, 0};
  n.update(self1.data(), nullptr, nullptr, nullptr, nullptr, nullptr, 2);
  n.update(self2.data(), nullptr, nullptr, nullptr, nullptr, nullptr, 2);
  const double beta = 0.99999;
  EXPECT_NEAR(n.mean(kObsSelf, 0), (2.0 * beta + 4.0) / (1.0 + beta), 1e-12);
  EXPECT_EQ(kObsNormBeta, beta);
}

// Padding rows of a batch (agents that do not exist in their env) do not move the statistics: a masked
// update equals the update from the real rows alone, and an update with no real row changes nothing.
TEST(NnObsNormalizer, RowMaskSkipsPaddingRows) {
  const ObsShape s = tiny_shape(2, 2);
  // Rows 0 and 2 are real, row 1 is padding with values that would shift every mean.
  const std::vector<float> self = {1, 2, 100, 100, 3, 4}, lidar = {1, 1, 100, 100, 3, 3},
                           boxes = {5, 6, 100, 100, 7, 8};
  const std::vector<uint8_t> mask = {1, 0, 1};
  const std::vector<float> self_real = {1, 2, 3, 4}, lidar_real = {1, 1, 3, 3}, boxes_real = {5, 6, 7, 8};
  ObsNormalizer masked(s, 0.9), real(s, 0.9);
  masked.update(self.data(), lidar.data(), nullptr, boxes.data(), nullptr, nullptr, 3, mask.data());
  real.update(self_real.data(), lidar_real.data(), nullptr, boxes_real.data(), nullptr, nullptr, 2);
  for (ObsKey k : {kObsSelf, kObsLidar, kObsBoxes}) {
    for (int j = 0; j < masked.features(k); ++j) {
      EXPECT_EQ(masked.mean(k, j), real.mean(k, j)) << "key " << k << " feature " << j;
      EXPECT_EQ(masked.std(k, j), real.std(k, j)) << "key " << k << " feature " << j;
    }
  }
  EXPECT_NEAR(masked.mean(kObsBoxes, 0), 6.5, 1e-12);
  const std::vector<uint8_t> none = {0, 0, 0};
  masked.update(self.data(), lidar.data(), nullptr, boxes.data(), nullptr, nullptr, 3, none.data());
  EXPECT_EQ(masked.debias(kObsSelf), real.debias(kObsSelf)) << "no real row: no update";
  EXPECT_EQ(masked.mean(kObsSelf, 0), real.mean(kObsSelf, 0));
}

// The trainer sums a rollout's statistics block by block, straight from the simulator: blocks added in row
// order to one Sums give the same bits as one update over all the rows (padding rows skipped alike), merged
// Sums of separate blocks the same statistics up to rounding, and nothing moves before apply().
TEST(NnObsNormalizer, BlockSumsEqualOneUpdate) {
  const ObsShape s = tiny_shape(2, 2);
  const std::vector<float> self = {1, 2, 100, 100, 3, 4, 0.5f, -7, 2.25f, 9},
                           lidar = {1, 1, 100, 100, 3, 3, 0.1f, 5, 6, 2},
                           boxes = {5, 6, 100, 100, 7, 8, 0.3f, -1, 4, 4};
  const std::vector<uint8_t> mask = {1, 0, 1, 1, 1};
  ObsNormalizer whole(s, 0.9), blocks(s, 0.9), merged(s, 0.9);
  for (int round = 0; round < 2; ++round) {
    whole.update(self.data(), lidar.data(), nullptr, boxes.data(), nullptr, nullptr, 5, mask.data());
    ObsNormalizer::Sums one = blocks.make_sums(), first = merged.make_sums(), second = merged.make_sums();
    blocks.add_rows(one, self.data(), lidar.data(), nullptr, boxes.data(), nullptr, nullptr, 2, mask.data());
    blocks.add_rows(one, self.data() + 4, lidar.data() + 4, nullptr, boxes.data() + 4, nullptr, nullptr, 3,
                    mask.data() + 2);
    merged.add_rows(second, self.data() + 4, lidar.data() + 4, nullptr, boxes.data() + 4, nullptr, nullptr, 3,
                    mask.data() + 2);
    merged.add_rows(first, self.data(), lidar.data(), nullptr, boxes.data(), nullptr, nullptr, 2,
                    mask.data());
    first.merge(second);
    EXPECT_EQ(one.rows[kObsSelf], 4);
    EXPECT_EQ(first.rows, one.rows);
    const double before = blocks.mean(kObsSelf, 0);
    ObsNormalizer::Sums dropped = blocks.make_sums();
    blocks.add_rows(dropped, self.data(), lidar.data(), nullptr, boxes.data(), nullptr, nullptr, 5);
    dropped.clear();  // what the trainer does with the sums of a discarded episode
    EXPECT_EQ(blocks.mean(kObsSelf, 0), before) << "the statistics moved before apply()";
    blocks.apply(one);
    merged.apply(first);
    for (ObsKey k : {kObsSelf, kObsLidar, kObsBoxes}) {
      EXPECT_EQ(whole.biased_mean(k), blocks.biased_mean(k)) << "key " << k;
      EXPECT_EQ(whole.biased_sq(k), blocks.biased_sq(k)) << "key " << k;
      EXPECT_EQ(whole.debias(k), blocks.debias(k)) << "key " << k;
      EXPECT_EQ(whole.debias(k), merged.debias(k)) << "key " << k;
      for (int j = 0; j < whole.features(k); ++j) {
        EXPECT_NEAR(whole.mean(k, j), merged.mean(k, j), 1e-12) << "key " << k;
        EXPECT_NEAR(whole.std(k, j), merged.std(k, j), 1e-9) << "key " << k;
      }
    }
  }
  EXPECT_NE(whole.mean(kObsSelf, 0), 0.0);
  // Empty sums change nothing.
  const double m = blocks.mean(kObsBoxes, 0);
  blocks.apply(blocks.make_sums());
  EXPECT_EQ(blocks.mean(kObsBoxes, 0), m);
  EXPECT_EQ(blocks.debias(kObsBoxes), whole.debias(kObsBoxes));
}

}  // namespace
}  // namespace hns::nn
