// PPO arithmetic against hand-computed values (paper appendix B).
#include "ppo/ppo_math.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace hns::ppo {
namespace {

constexpr GaeParams kHalf{0.5, 0.5};  // γ = λ = 0.5 keeps the hand arithmetic exact

struct Gae {
  std::vector<float> adv, ret;
};
Gae run_gae(std::vector<float> r, std::vector<float> v, std::vector<uint8_t> last, GaeParams p = kHalf) {
  Gae out{std::vector<float>(r.size()), std::vector<float>(r.size())};
  gae_window(r, v, last, p, out.adv, out.ret);
  return out;
}

// rewards (1, 0, 2), values V(s_0..s_3) = (0.5, 1, 0, 4): δ = (1, -1, 4).
TEST(Gae, SingleEpisodeWindowBootstrapsFromTheStateAfterIt) {
  const Gae g = run_gae({1, 0, 2}, {0.5f, 1.0f, 0.0f, 4.0f}, {0, 0, 0});
  EXPECT_FLOAT_EQ(g.adv[2], 4.0f);  // H = 1: δ_2 = 2 + 0.5·4 - 0
  EXPECT_FLOAT_EQ(g.adv[1], 0.0f);  // δ_1 + γλ·Â_2 = -1 + 0.25·4
  EXPECT_FLOAT_EQ(g.adv[0], 1.0f);  // δ_0 + γλ·Â_1 = 1 + 0
  EXPECT_FLOAT_EQ(g.ret[0], 1.5f);  // Ĝ = Â + V
  EXPECT_FLOAT_EQ(g.ret[1], 1.0f);
  EXPECT_FLOAT_EQ(g.ret[2], 4.0f);
}

// A new episode starts at step 2: step 1 is its episode's last (no bootstrap, no carry across).
TEST(Gae, EpisodeBoundaryInsideWindowCutsTheRecurrence) {
  const Gae g = run_gae({1, 0, 2}, {0.5f, 1.0f, 0.0f, 4.0f}, {0, 1, 0});
  EXPECT_FLOAT_EQ(g.adv[2], 4.0f);   // the new episode's first step still bootstraps from V(s_3)
  EXPECT_FLOAT_EQ(g.adv[1], -1.0f);  // r_1 - V(s_1), nothing from step 2
  EXPECT_FLOAT_EQ(g.adv[0], 0.75f);  // 1 + 0.25·(-1)
  EXPECT_FLOAT_EQ(g.ret[1], 0.0f);
}

TEST(Gae, EpisodeEndingAtWindowEndDoesNotBootstrap) {
  const Gae g = run_gae({1, 0, 2}, {0.5f, 1.0f, 0.0f, 4.0f}, {0, 0, 1});
  EXPECT_FLOAT_EQ(g.adv[2], 2.0f);
  EXPECT_FLOAT_EQ(g.adv[1], -0.5f);
  EXPECT_FLOAT_EQ(g.adv[0], 0.875f);
}

// With λ = 1 and no episode end, Ĝ_0 is the discounted return plus the discounted bootstrap.
TEST(Gae, LambdaOneGivesMonteCarloReturns) {
  const Gae g = run_gae({1, 1, 1, 1}, {3, -2, 7, 0.5f, 10}, {0, 0, 0, 0}, GaeParams{0.9, 1.0});
  const double expected = 1 + 0.9 + 0.81 + 0.729 + 0.6561 * 10;
  EXPECT_NEAR(g.ret[0], expected, 1e-5);
}

TEST(Zscore, OverMaskedEntriesOnly) {
  std::vector<float> x = {1, 2, 3, 100, 5};
  const std::vector<uint8_t> m = {1, 1, 1, 0, 1};
  zscore(x, m);
  double mean = 0, sq = 0;
  for (int i : {0, 1, 2, 4}) mean += x[i] / 4.0, sq += x[i] * x[i] / 4.0;
  EXPECT_NEAR(mean, 0.0, 1e-6);
  EXPECT_NEAR(sq, 1.0, 1e-5);
  EXPECT_EQ(x[3], 0.0f) << "padding is zeroed";
}

TEST(PolicyLoss, HandComputedClippedSurrogate) {
  const std::vector<float> new_logp = {0.0f, 0.5f, -0.5f, -0.1f, 3.0f};
  const std::vector<float> old_logp = {0, 0, 0, 0, 0};
  const std::vector<float> adv = {2, 1, -1, -1, 50};
  const std::vector<uint8_t> mask = {1, 1, 1, 1, 0};
  std::vector<float> grad(5);
  const PolicyLossStats s = ppo_policy_loss(new_logp, old_logp, adv, mask, 0.2f, grad);
  const double r3 = std::exp(-0.1);
  // Surrogates: 2 (ratio 1), 1.2 (clipped at 1.2), -0.8 (clipped at 0.8), -r3 (inside the clip range).
  EXPECT_NEAR(s.loss, -(2 + 1.2 - 0.8 - r3) / 4, 1e-6);
  // KL estimate per entry: (r - 1) - log r, never negative.
  const auto k = [](double log_r) { return std::exp(log_r) - 1.0 - log_r; };
  EXPECT_NEAR(s.approx_kl, (k(0) + k(0.5) + k(-0.5) + k(-0.1)) / 4, 1e-7);
  EXPECT_GT(s.approx_kl, 0.0);
  EXPECT_DOUBLE_EQ(s.clip_frac, 0.5);
  EXPECT_EQ(s.count, 4);
  EXPECT_NEAR(grad[0], -2.0 / 4, 1e-7);
  EXPECT_EQ(grad[1], 0.0f) << "clipped: no gradient";
  EXPECT_EQ(grad[2], 0.0f) << "clipped: no gradient";
  EXPECT_NEAR(grad[3], r3 / 4, 1e-7);
  EXPECT_EQ(grad[4], 0.0f) << "masked";
}

TEST(PolicyLoss, GradientMatchesFiniteDifferences) {
  std::vector<float> logp = {-0.05f, 0.1f, 0.15f, -0.3f, 0.02f, 0.0f};
  const std::vector<float> old = {0, 0, 0, 0, 0, 0};
  const std::vector<float> adv = {1.5f, -0.7f, 0.3f, 2.0f, -1.1f, 0.4f};
  const std::vector<uint8_t> mask = {1, 1, 1, 1, 1, 1};
  std::vector<float> grad(6), scratch(6);
  ppo_policy_loss(logp, old, adv, mask, 0.2f, grad);
  for (size_t i = 0; i < logp.size(); ++i) {
    const float h = 1e-3f;
    std::vector<float> up = logp, down = logp;
    up[i] += h;
    down[i] -= h;
    const double fd = (ppo_policy_loss(up, old, adv, mask, 0.2f, scratch).loss -
                       ppo_policy_loss(down, old, adv, mask, 0.2f, scratch).loss) /
                      (2 * h);
    EXPECT_NEAR(grad[i], fd, 2e-4) << i;
  }
}

TEST(ValueLoss, HalfMeanSquaredErrorAndGradient) {
  const std::vector<float> pred = {1, 2, 9}, target = {0, 4, -9};
  const std::vector<uint8_t> mask = {1, 1, 0};
  std::vector<float> grad(3);
  EXPECT_DOUBLE_EQ(value_loss(pred, target, mask, grad), 1.25);
  EXPECT_FLOAT_EQ(grad[0], 0.5f);
  EXPECT_FLOAT_EQ(grad[1], -1.0f);
  EXPECT_FLOAT_EQ(grad[2], 0.0f);
}

TEST(ExplainedVariance, PerfectConstantAndWorse) {
  const std::vector<float> target = {1, 2, 3, 4};
  const std::vector<uint8_t> mask = {1, 1, 1, 1};
  EXPECT_DOUBLE_EQ(explained_variance(target, target, mask), 1.0);
  const std::vector<float> mean = {2.5f, 2.5f, 2.5f, 2.5f};
  EXPECT_NEAR(explained_variance(mean, target, mask), 0.0, 1e-12);
  const std::vector<float> reversed = {4, 3, 2, 1};
  EXPECT_LT(explained_variance(reversed, target, mask), 0.0);
}

}  // namespace
}  // namespace hns::ppo
