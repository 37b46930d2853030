// Adam against a step computed by hand, with weight decay on kernels only and global-norm clipping.
#include "nn/adam.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
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
  Fixture f;
  Adam adam(f.layout, {});
  ParamStore store(f.layout);
  float* p = store.values();
  float* g = store.grads();
  p[f.w] = 1.0f, p[f.w + 1] = 2.0f, p[f.b] = 3.0f;
  g[f.w] = 0.5f, g[f.w + 1] = NAN, g[f.b] = 1.0f;
  const AdamStepInfo info = adam.step(p, g);
  EXPECT_FALSE(info.applied);
  EXPECT_EQ(p[f.w], 1.0f);
  EXPECT_EQ(p[f.b], 3.0f);
  EXPECT_EQ(adam.m()[f.w], 0.0f);
  EXPECT_EQ(adam.steps(), 0);
  g[f.w + 1] = 0.25f;
  EXPECT_TRUE(adam.step(p, g).applied);
  EXPECT_NE(p[f.w], 1.0f);
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

}  // namespace
}  // namespace hns::nn
