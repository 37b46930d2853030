// The transfer suite's statistics (mean and 90 % interval over seeds, normalised return) against
// hand-computed values, and the random policy's return: the same for any thread count, and at the level the
// tasks' rewards give a policy that does nothing on purpose.
#include "ppo/eval.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace hns::ppo {
namespace {

TEST(EvalStatistics, MeanAndStudentTInterval) {
  const std::vector<double> three = {1.0, 2.0, 3.0};
  const MeanInterval m = mean_interval90(three);
  EXPECT_EQ(m.n, 3);
  EXPECT_DOUBLE_EQ(m.mean, 2.0);
  // s = 1, t(0.95, 2) = 2.920: half width 2.920 / sqrt(3).
  EXPECT_NEAR(m.hi - m.mean, 2.920 / std::sqrt(3.0), 1e-12);
  EXPECT_NEAR(m.mean - m.lo, 2.920 / std::sqrt(3.0), 1e-12);
  const std::vector<double> one = {4.5};
  const MeanInterval single = mean_interval90(one);
  EXPECT_EQ(single.n, 1);
  EXPECT_EQ(single.lo, 4.5);
  EXPECT_EQ(single.hi, 4.5);
  EXPECT_EQ(mean_interval90({}).n, 0);
  // Many seeds: close to the normal's 1.645.
  std::vector<double> many;
  for (int i = 0; i < 200; ++i) many.push_back(i % 2 == 0 ? 1.0 : -1.0);
  const MeanInterval big = mean_interval90(many);
  const double s = std::sqrt(200.0 / 199.0);
  EXPECT_NEAR((big.hi - big.mean) / (s / std::sqrt(200.0)), 1.653, 0.005);
}

TEST(EvalStatistics, NormalisedReturn) {
  EXPECT_DOUBLE_EQ(normalised(0.36, 0.36, 10.0), 0.0);
  EXPECT_DOUBLE_EQ(normalised(10.0, 0.36, 10.0), 1.0);
  EXPECT_DOUBLE_EQ(normalised(-11.0, -12.0, -10.0), 0.5);  // shelter's negative returns
  EXPECT_DOUBLE_EQ(normalised(3.0, 2.0, 2.0), 0.0);        // nothing beat the random policy
}

TEST(EvalRandomPolicy, SameForAnyThreadCountAndAtTheRandomLevel) {
  TrainConfig c;
  c.scene = "lockbox";
  c.envs = 8;
  c.seed = 5;
  c.threads = 1;
  const double one = random_policy_return(c, 24);
  c.threads = 2;
  EXPECT_EQ(random_policy_return(c, 24), one);
  // Random actions lock the cube now and then: far below the 55 of a policy that locks it at once.
  EXPECT_GT(one, -1.0);
  EXPECT_LT(one, 15.0);
  c.seed = 6;
  EXPECT_NE(random_policy_return(c, 24), one);
  EXPECT_THROW(random_policy_return(c, 0), physics::ConfigError);
}

}  // namespace
}  // namespace hns::ppo
