// Observation normaliser: debiased EMA statistics, the std floor, and the float view the kernels read.
#include "nn/obs_normalizer.hpp"
#include "nn/entity_net.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace hns::nn {
namespace {

TEST(NnObsNormalizer, DebiasedEmaAndFloor) {
  ObsShape s;
  s.self_features = 2;
  s.max_agents = 1;
  s.max_boxes = 1;
  s.box_features = 1;
  s.max_ramps = 0;
  s.lidar_rays = 3;
  ObsNormalizer n(s, 0.9);
  // Identity before the first update.
  EXPECT_EQ(n.view().mean[kObsSelf][0], 0.0f);
  EXPECT_EQ(n.view().inv_std[kObsSelf][0], 1.0f);
  // Batch 1: self feature 0 in {1, 3}, feature 1 constant 5; lidar {0..5}.
  const std::vector<float> self1 = {1, 5, 3, 5}, lidar1 = {0, 1, 2, 3, 4, 5}, boxes1 = {2, 2};
  n.update(self1.data(), lidar1.data(), nullptr, boxes1.data(), nullptr, 2);
  EXPECT_NEAR(n.mean(kObsSelf, 0), 2.0, 1e-12);  // debiased: exactly the batch mean after one update
  EXPECT_NEAR(n.std(kObsSelf, 0), 1.0, 1e-9);
  EXPECT_NEAR(n.std(kObsSelf, 1), 0.1, 1e-9);  // constant feature: the std floor sqrt(1e-2)
  EXPECT_NEAR(n.mean(kObsLidar, 0), 2.5, 1e-12);
  EXPECT_FLOAT_EQ(n.view().mean[kObsLidar][2], 2.5f);  // one channel shared by every ray
  // Batch 2: feature 0 constant 4. EMA with beta 0.9: weights 0.1 * 0.9 and 0.1, debias 0.19.
  const std::vector<float> self2 = {4, 5, 4, 5};
  n.update(self2.data(), nullptr, nullptr, nullptr, nullptr, 2);
  const double mean = (0.09 * 2.0 + 0.1 * 4.0) / 0.19;
  const double sq = (0.09 * 5.0 + 0.1 * 16.0) / 0.19;
  EXPECT_NEAR(n.mean(kObsSelf, 0), mean, 1e-12);
  EXPECT_NEAR(n.std(kObsSelf, 0), std::sqrt(sq - mean * mean), 1e-9);
  EXPECT_FLOAT_EQ(n.view().inv_std[kObsSelf][0], static_cast<float>(1.0 / std::sqrt(sq - mean * mean)));
}

}  // namespace
}  // namespace hns::nn
