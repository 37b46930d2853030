// Categorical heads: log-probability, entropy, their gradients, and deterministic sampling.
#include "nn/heads.hpp"

#include "test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

namespace hns::nn {
namespace {

using testing::expect_gradient_matches;
using testing::random_vector;
using testing::to_double;

const std::vector<int> kSizes = {11, 11, 11, 2, 2};

// Double reference of sum_h log p_h(a_h) and sum_h H_h for one row.
std::pair<double, double> reference(const double* l, const int32_t* a) {
  double lp = 0.0, ent = 0.0;
  int off = 0;
  for (size_t h = 0; h < kSizes.size(); ++h) {
    const int n = kSizes[h];
    double mx = l[off];
    for (int i = 1; i < n; ++i) mx = std::max(mx, l[off + i]);
    double s = 0.0;
    for (int i = 0; i < n; ++i) s += std::exp(l[off + i] - mx);
    const double lse = mx + std::log(s);
    lp += l[off + a[h]] - lse;
    for (int i = 0; i < n; ++i) ent -= std::exp(l[off + i] - lse) * (l[off + i] - lse);
    off += n;
  }
  return {lp, ent};
}

TEST(NnHeads, LayoutOfHideAndSeekActions) {
  CategoricalHeads heads(kSizes);
  EXPECT_EQ(heads.num_logits(), 37);
  EXPECT_EQ(heads.num_heads(), 5);
}

TEST(NnHeads, LogProbEntropyAndGradients) {
  CategoricalHeads heads(kSizes);
  const int rows = 4;
  const auto logits = random_vector(rows * 37, 1, -3.0f, 3.0f);
  std::vector<int32_t> actions(rows * 5);
  for (int i = 0; i < rows * 5; ++i) actions[i] = (i * 7) % kSizes[i % 5];
  std::vector<float> logp(rows), ent(rows);
  heads.log_prob_entropy(CMat(logits.data(), rows, 37), actions.data(), logp.data(), ent.data());
  const auto ld = to_double(logits);
  for (int r = 0; r < rows; ++r) {
    const auto [lp, h] = reference(ld.data() + r * 37, actions.data() + r * 5);
    EXPECT_NEAR(logp[r], lp, 1e-5);
    EXPECT_NEAR(ent[r], h, 1e-5);
  }
  // Uniform logits: entropy = 3 ln 11 + 2 ln 2.
  std::vector<float> flat(37, 0.5f);
  heads.log_prob_entropy(CMat(flat.data(), 1, 37), actions.data(), logp.data(), ent.data());
  EXPECT_NEAR(ent[0], 3 * std::log(11.0) + 2 * std::log(2.0), 1e-5);
  EXPECT_NEAR(logp[0], -(3 * std::log(11.0) + 2 * std::log(2.0)), 1e-5);
  // d(a logp + b H)/dlogits against finite differences.
  const auto gl = random_vector(rows, 2), ge = random_vector(rows, 3);
  std::vector<float> d(rows * 37);
  heads.backward(CMat(logits.data(), rows, 37), actions.data(), gl.data(), ge.data(),
                 Mat(d.data(), rows, 37));
  auto loss = [&](const std::vector<double>& v) {
    double s = 0.0;
    for (int r = 0; r < rows; ++r) {
      const auto [lp, h] = reference(v.data() + r * 37, actions.data() + r * 5);
      s += gl[r] * lp + ge[r] * h;
    }
    return s;
  };
  expect_gradient_matches(loss, ld, d, 1e-5, "categorical heads");
}

// The PPO loss takes the gradient from what log_prob_entropy saved: the same bits as backward() on the
// logits (with and without actions, with either gradient input missing), and the save changes nothing else.
TEST(NnHeads, BackwardFromSavedSoftmaxesEqualsBackwardBitForBit) {
  CategoricalHeads heads(kSizes);
  const int rows = 23;
  const auto logits = random_vector(rows * 37, 4, -6.0f, 6.0f);
  std::vector<int32_t> actions(rows * 5);
  for (int i = 0; i < rows * 5; ++i) actions[i] = (i * 5 + 3) % kSizes[i % 5];
  const auto gl = random_vector(rows, 5), ge = random_vector(rows, 6);
  const CMat l(logits.data(), rows, 37);
  std::vector<float> logp(rows), ent(rows), logp_saving(rows), ent_saving(rows);
  std::vector<double> saved(heads.saved_doubles(rows));
  heads.log_prob_entropy(l, actions.data(), logp.data(), ent.data());
  heads.log_prob_entropy(l, actions.data(), logp_saving.data(), ent_saving.data(), saved.data());
  EXPECT_EQ(std::memcmp(logp.data(), logp_saving.data(), sizeof(float) * rows), 0);
  EXPECT_EQ(std::memcmp(ent.data(), ent_saving.data(), sizeof(float) * rows), 0);
  for (const bool with_actions : {true, false})
    for (const int inputs : {3, 1, 2}) {  // bit 0: d_logp, bit 1: d_entropy
      const int32_t* a = with_actions ? actions.data() : nullptr;
      const float* dl = (inputs & 1) != 0 ? gl.data() : nullptr;
      const float* de = (inputs & 2) != 0 ? ge.data() : nullptr;
      std::vector<float> want(rows * 37, -1.0f), got(rows * 37, -2.0f);
      heads.backward(l, a, dl, de, Mat(want.data(), rows, 37));
      heads.backward_saved(saved.data(), rows, a, dl, de, Mat(got.data(), rows, 37));
      EXPECT_EQ(std::memcmp(want.data(), got.data(), sizeof(float) * want.size()), 0)
          << "actions " << with_actions << " inputs " << inputs;
    }
}

TEST(NnHeads, SamplingIsDeterministicAndFollowsTheDistribution) {
  CategoricalHeads heads({3});
  // p = softmax(log [0.2, 0.5, 0.3]).
  const std::vector<float> logits = {std::log(0.2f), std::log(0.5f), std::log(0.3f)};
  std::vector<int> counts(3, 0);
  const int n = 10000;
  for (int i = 0; i < n; ++i) {
    const float u = (static_cast<float>(i) + 0.5f) / n;
    int32_t a = -1;
    float lp = 0.0f;
    heads.sample(CMat(logits.data(), 1, 3), &u, &a, &lp);
    ASSERT_GE(a, 0);
    ASSERT_LT(a, 3);
    EXPECT_FLOAT_EQ(lp, logits[a]);
    ++counts[a];
  }
  // Inverse CDF over evenly spaced u gives the exact proportions.
  EXPECT_NEAR(counts[0], 2000, 2);
  EXPECT_NEAR(counts[1], 5000, 2);
  EXPECT_NEAR(counts[2], 3000, 2);
  // Same uniforms, same actions; u at the top end stays in range.
  const float u = 0.9999999f;
  int32_t a = -1;
  heads.sample(CMat(logits.data(), 1, 3), &u, &a, nullptr);
  EXPECT_EQ(a, 2);
  std::vector<int32_t> best(1);
  heads.argmax(CMat(logits.data(), 1, 3), best.data());
  EXPECT_EQ(best[0], 1);
}

}  // namespace
}  // namespace hns::nn
