// Adam against a step computed by hand, with weight decay on kernels only and global-norm clipping.
#include "nn/adam.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <cstring>
#include <random>
#include <vector>

namespace hns::nn {
namespace {

struct Fixture {
  ParamLayout layout;
  size_t w = 0, b = 0;
  Fixture() {
    w = layout.add_kernel_xavier("w", 1, 2, 1.0f, 2.0f);  // decayed
    b = layout.add_vector("b", 1, Init::kZeros);          // not decayed
  }
};

TEST(NnAdam, FirstTwoStepsMatchHandComputation) {
  Fixture f;
  AdamConfig cfg;
  cfg.lr = 0.1f;
  Adam adam(f.layout, cfg);
  ParamStore store(f.layout);
  float* p = store.values();
  float* g = store.grads();
  p[f.w] = 1.0f, p[f.w + 1] = -2.0f, p[f.b] = 0.5f;
  // Step 1: g = (0.5, -1, 2). m = 0.1 g, v = 0.001 g^2, lr_t = 0.1 sqrt(0.001) / 0.1.
  g[f.w] = 0.5f, g[f.w + 1] = -1.0f, g[f.b] = 2.0f;
  adam.step(p, g);
  const double gs1[3] = {0.5, -1.0, 2.0};
  double m[3], v[3], want[3] = {1.0, -2.0, 0.5};
  for (int i = 0; i < 3; ++i) {
    m[i] = 0.1 * gs1[i];
    v[i] = 0.001 * gs1[i] * gs1[i];
    want[i] -= 0.1 * std::sqrt(1 - 0.999) / (1 - 0.9) * m[i] / (std::sqrt(v[i]) + 1e-8);
  }
  EXPECT_NEAR(p[f.w], want[0], 1e-6);
  EXPECT_NEAR(p[f.w + 1], want[1], 1e-6);
  EXPECT_NEAR(p[f.b], want[2], 1e-6);
  EXPECT_NEAR(p[f.w], 0.9, 1e-5);  // the first Adam step moves each weight by about lr
  // Step 2: g = (-0.25, 0.5, 1).
  const double gs2[3] = {-0.25, 0.5, 1.0};
  g[f.w] = -0.25f, g[f.w + 1] = 0.5f, g[f.b] = 1.0f;
  adam.step(p, g);
  const double lr_t = 0.1 * std::sqrt(1 - 0.999 * 0.999) / (1 - 0.9 * 0.9);
  for (int i = 0; i < 3; ++i) {
    m[i] = 0.9 * m[i] + 0.1 * gs2[i];
    v[i] = 0.999 * v[i] + 0.001 * gs2[i] * gs2[i];
    want[i] -= lr_t * m[i] / (std::sqrt(v[i]) + 1e-8);
  }
  EXPECT_NEAR(p[f.w], want[0], 1e-6);
  EXPECT_NEAR(p[f.w + 1], want[1], 1e-6);
  EXPECT_NEAR(p[f.b], want[2], 1e-6);
  EXPECT_EQ(adam.steps(), 2);
}

TEST(NnAdam, WeightDecayOnKernelsThenGlobalNormClipping) {
  Fixture f;
  AdamConfig cfg;
  cfg.lr = 0.01f;
  cfg.weight_decay = 0.5f;
  cfg.max_grad_norm = 1.0f;
  Adam adam(f.layout, cfg);
  ParamStore store(f.layout);
  float* p = store.values();
  float* g = store.grads();
  p[f.w] = 2.0f, p[f.w + 1] = 0.0f, p[f.b] = 4.0f;
  g[f.w] = 2.0f, g[f.w + 1] = 3.0f, g[f.b] = 0.0f;
  // Decay: g_w += 0.5 * w -> (3, 3), bias untouched -> 0. Norm sqrt(18); clipped to 1.
  const AdamStepInfo info = adam.step(p, g);
  EXPECT_NEAR(info.grad_norm, std::sqrt(18.0), 1e-6);
  EXPECT_NEAR(info.clip_scale, 1.0 / std::sqrt(18.0), 1e-7);
  EXPECT_NEAR(g[f.w], 3.0 / std::sqrt(18.0), 1e-6);
  EXPECT_NEAR(g[f.w + 1], 3.0 / std::sqrt(18.0), 1e-6);
  EXPECT_EQ(g[f.b], 0.0f);
  EXPECT_EQ(p[f.b], 4.0f);  // zero gradient, no decay: unchanged
  EXPECT_NEAR(p[f.w], 2.0 - 0.01, 1e-6);
  EXPECT_NEAR(p[f.w + 1], -0.01, 1e-6);
  // Below the limit nothing is clipped.
  g[f.w] = 0.1f, g[f.w + 1] = 0.0f, g[f.b] = 0.0f;
  cfg.weight_decay = 0.0f;
  Adam plain(f.layout, cfg);
  EXPECT_FLOAT_EQ(plain.step(p, g).clip_scale, 1.0f);
}

TEST(NnAdam, NonFiniteGradientChangesNothing) {
  // With weight decay and clipping on, after one good step: a refused step leaves the parameters, both
  // moments and the step count as they were (the gradient buffer is the step's scratch).
  Fixture f;
  AdamConfig cfg;
  cfg.weight_decay = 0.1f;
  cfg.max_grad_norm = 0.5f;
  Adam adam(f.layout, cfg);
  ParamStore store(f.layout);
  float* p = store.values();
  float* g = store.grads();
  p[f.w] = 1.0f, p[f.w + 1] = 2.0f, p[f.b] = 3.0f;
  g[f.w] = 0.5f, g[f.w + 1] = -0.25f, g[f.b] = 1.0f;
  ASSERT_TRUE(adam.step(p, g).applied);
  const size_t n = store.buffer_floats();
  const std::vector<float> p0(p, p + n), m0(adam.m().data(), adam.m().data() + n),
      v0(adam.v().data(), adam.v().data() + n);
  g[f.w] = 0.5f, g[f.w + 1] = NAN, g[f.b] = 1.0f;
  const AdamStepInfo info = adam.step(p, g);
  EXPECT_FALSE(info.applied);
  EXPECT_EQ(std::vector<float>(p, p + n), p0);
  EXPECT_EQ(std::vector<float>(adam.m().data(), adam.m().data() + n), m0);
  EXPECT_EQ(std::vector<float>(adam.v().data(), adam.v().data() + n), v0);
  EXPECT_EQ(adam.steps(), 1);
  g[f.w + 1] = 0.25f;
  EXPECT_TRUE(adam.step(p, g).applied);
  EXPECT_NE(p[f.w], p0[f.w]);
}

TEST(NnAdam, GlobalNormIsExact) {
  std::vector<float> x(100000);
  double want = 0.0;
  for (size_t i = 0; i < x.size(); ++i) {
    x[i] = static_cast<float>(i % 7) - 3.0f;
    want += static_cast<double>(x[i]) * x[i];
  }
  EXPECT_DOUBLE_EQ(global_norm(x.data(), x.size()), std::sqrt(want));
}

// The norm's summation order is its contract (bit-identical results at any thread count): each block of
// kNormBlock floats summed in index order, then the blocks in order. Random floats, so that any other order
// would round differently; whole groups of blocks, a partial group and a short last block.
TEST(NnAdam, GlobalNormSumsEachBlockInOrderThenTheBlocks) {
  std::mt19937 rng(7);
  std::normal_distribution<float> dist(0.0f, 1.0f);
  for (size_t n : {size_t(1), kNormBlock - 1, 8 * kNormBlock, 19 * kNormBlock + 4321}) {
    std::vector<float> x(n);
    for (float& v : x) v = dist(rng) * std::exp(dist(rng));
    double total = 0.0;
    for (size_t b = 0; b < n; b += kNormBlock) {
      double s = 0.0;
      for (size_t i = b; i < std::min(n, b + kNormBlock); ++i) s += static_cast<double>(x[i]) * x[i];
      total += s;
    }
    EXPECT_EQ(global_norm(x.data(), n), std::sqrt(total)) << n << " floats";
  }
}

// The step is vectorised; each element must see exactly the arithmetic of the documented formula, in float,
// in this order, whichever lane or tail it falls in.
TEST(NnAdam, StepEqualsTheScalarFormulaBitForBit) {
  ParamLayout layout;
  layout.add_kernel_xavier("w", 3 * 1024, 100, 1.0f, 2.0f);  // decayed
  layout.add_vector("b", 4099, Init::kZeros);                // not decayed; odd sizes leave tails
  const size_t n = layout.buffer_floats();
  AdamConfig cfg;
  cfg.lr = 0.003f;
  cfg.weight_decay = 0.01f;
  cfg.max_grad_norm = 0.5f;
  Adam adam(layout, cfg);
  std::mt19937 rng(11);
  std::normal_distribution<float> dist(0.0f, 1.0f);
  std::vector<float> p(n), g(n), m(n), v(n), decay(n, 0.0f);
  for (const ParamSlice& s : layout.slices())
    if (s.decay)
      std::fill(decay.begin() + ptrdiff_t(s.offset), decay.begin() + ptrdiff_t(s.offset + s.size()), 1.0f);
  for (size_t i = 0; i < n; ++i) {
    p[i] = dist(rng);
    m[i] = adam.m()[i] = 0.1f * dist(rng);
    v[i] = adam.v()[i] = 0.01f * std::abs(dist(rng));
  }
  adam.set_steps(3);
  for (int step = 0; step < 2; ++step) {
    for (size_t i = 0; i < n; ++i) g[i] = dist(rng);
    std::vector<float> p_ref = p, g_ref = g;
    double sq = 0.0;
    for (size_t i = 0; i < n; ++i) {
      g_ref[i] += cfg.weight_decay * decay[i] * p_ref[i];
    }
    for (size_t b = 0; b < n; b += kNormBlock) {
      double s = 0.0;
      for (size_t i = b; i < std::min(n, b + kNormBlock); ++i) s += static_cast<double>(g_ref[i]) * g_ref[i];
      sq += s;
    }
    const double norm = std::sqrt(sq);
    const float scale = norm > cfg.max_grad_norm ? static_cast<float>(cfg.max_grad_norm / norm) : 1.0f;
    const double t = double(adam.steps() + 1);
    const float lr_t = static_cast<float>(cfg.lr * std::sqrt(1.0 - std::pow(double(cfg.beta2), t)) /
                                          (1.0 - std::pow(double(cfg.beta1), t)));
    for (size_t i = 0; i < n; ++i) {
      const float gi = g_ref[i] * scale;
      g_ref[i] = gi;
      m[i] = cfg.beta1 * m[i] + (1.0f - cfg.beta1) * gi;
      v[i] = cfg.beta2 * v[i] + (1.0f - cfg.beta2) * gi * gi;
      p_ref[i] -= lr_t * m[i] / (std::sqrt(v[i]) + cfg.eps);
    }
    const AdamStepInfo info = adam.step(p.data(), g.data());
    ASSERT_TRUE(info.applied);
    EXPECT_EQ(info.grad_norm, norm);
    EXPECT_EQ(std::memcmp(g.data(), g_ref.data(), n * sizeof(float)), 0) << "gradient, step " << step;
    EXPECT_EQ(std::memcmp(adam.m().data(), m.data(), n * sizeof(float)), 0) << "first moment, step " << step;
    EXPECT_EQ(std::memcmp(adam.v().data(), v.data(), n * sizeof(float)), 0) << "second moment, step " << step;
    EXPECT_EQ(std::memcmp(p.data(), p_ref.data(), n * sizeof(float)), 0) << "parameters, step " << step;
    p = p_ref;
  }
}

}  // namespace
}  // namespace hns::nn
