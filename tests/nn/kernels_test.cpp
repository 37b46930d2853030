// SIMD kernels equal their scalar reference paths bit for bit, for every tail length 0 .. 2 * width + 1, and
// agree with plain double-precision formulas.
#include "nn/kernels.hpp"
#include "nn/simd.hpp"

#include "test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace hns::nn {
namespace {

using testing::random_mask;
using testing::random_vector;

int max_n() {
  return 2 * kernels::simd_width() + 1;
}

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}

TEST(NnSimd, ExpTanhSigmoidAccuracy) {
  double worst_exp = 0.0, worst_tanh = 0.0, worst_sig = 0.0;
  for (int i = -20000; i <= 20000; ++i) {
    const float x = static_cast<float>(i) * 0.004f;  // [-80, 80]
    const double e = std::exp(static_cast<double>(x));
    worst_exp = std::max(worst_exp, std::fabs(simd::exp(x) - e) / e);
    const float xt = x * 0.1f;
    worst_tanh = std::max(worst_tanh, std::fabs(simd::tanh(xt) - std::tanh(static_cast<double>(xt))));
    worst_sig =
        std::max(worst_sig, std::fabs(simd::sigmoid(xt) - 1.0 / (1.0 + std::exp(-static_cast<double>(xt)))));
  }
  EXPECT_LT(worst_exp, 3e-7);
  EXPECT_LT(worst_tanh, 2e-7);
  EXPECT_LT(worst_sig, 2e-7);
  // Relative accuracy of tanh near 0 (the series branch).
  EXPECT_NEAR(simd::tanh(1e-4f), std::tanh(1e-4), 1e-11);
  EXPECT_EQ(simd::tanh(-0.5f), -simd::tanh(0.5f));
  EXPECT_EQ(simd::tanh(30.0f), 1.0f);
  EXPECT_EQ(simd::exp(-1e10f) * 0.0f, 0.0f);
}

TEST(NnSimd, VectorAndScalarTranscendentalsAgree) {
  const int w = simd::kWidth;
  const auto x = random_vector(w * 64, 3, -20.0f, 20.0f);
  for (size_t i = 0; i + w <= x.size(); i += w) {
    const simd::Batch b = simd::Batch::load_unaligned(x.data() + i);
    float e[simd::kWidth], t[simd::kWidth], s[simd::kWidth];
    simd::exp(b).store_unaligned(e);
    simd::tanh(b).store_unaligned(t);
    simd::sigmoid(b).store_unaligned(s);
    for (int l = 0; l < w; ++l) {
      EXPECT_EQ(e[l], simd::exp(x[i + l]));
      EXPECT_EQ(t[l], simd::tanh(x[i + l]));
      EXPECT_EQ(s[l], simd::sigmoid(x[i + l]));
    }
  }
}

// The vector max/min (one instruction each) give what the scalar rule a > b ? a : b (a < b ? a : b) gives,
// lane by lane and bit by bit, for NaNs, signed zeros, infinities and ordinary values in every pairing.
TEST(NnSimd, MaxMinFollowTheScalarRule) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const std::vector<float> values = {0.0f, -0.0f, 1.0f, -1.0f, 2.5f, -87.3f, inf, -inf, nan, -nan, 1e-40f};
  const int w = simd::kWidth;
  std::vector<float> a, b;
  for (float x : values)
    for (float y : values) {
      a.push_back(x);
      b.push_back(y);
    }
  while (a.size() % w != 0) {
    a.push_back(3.0f);
    b.push_back(-3.0f);
  }
  auto bits = [](float x) {
    uint32_t u;
    std::memcpy(&u, &x, sizeof u);
    return u;
  };
  for (size_t i = 0; i < a.size(); i += w) {
    const simd::Batch va = simd::Batch::load_unaligned(a.data() + i);
    const simd::Batch vb = simd::Batch::load_unaligned(b.data() + i);
    float mx[simd::kWidth], mn[simd::kWidth];
    simd::max(va, vb).store_unaligned(mx);
    simd::min(va, vb).store_unaligned(mn);
    for (int l = 0; l < w; ++l) {
      const float x = a[i + l], y = b[i + l];
      EXPECT_EQ(bits(mx[l]), bits(x > y ? x : y)) << "max(" << x << ", " << y << ")";
      EXPECT_EQ(bits(mn[l]), bits(x < y ? x : y)) << "min(" << x << ", " << y << ")";
      EXPECT_EQ(bits(simd::max(x, y)), bits(mx[l]));
      EXPECT_EQ(bits(simd::min(x, y)), bits(mn[l]));
    }
  }
}

TEST(NnKernels, NormalizeObsMatchesScalarAndFormula) {
  for (int n = 0; n <= max_n(); ++n) {
    const int rows = 5;
    const auto x = random_vector(rows * n, 10 + n, -30.0f, 30.0f);
    const auto mean = random_vector(n, 20 + n, -2.0f, 2.0f);
    const auto inv_std = random_vector(n, 30 + n, 0.1f, 3.0f);
    auto mask = random_mask(rows, 40 + n);
    std::vector<float> y(rows * n, 7.0f), ys(rows * n, 7.0f);
    kernels::normalize_obs(x.data(), mean.data(), inv_std.data(), mask.data(), rows, n, y.data());
    kernels::normalize_obs_scalar(x.data(), mean.data(), inv_std.data(), mask.data(), rows, n, ys.data());
    EXPECT_TRUE(same_bits(y, ys)) << "n = " << n;
    for (int r = 0; r < rows; ++r)
      for (int f = 0; f < n; ++f) {
        const double want =
            mask[r] != 0.0f
                ? std::clamp((x[r * n + f] - mean[f]) * static_cast<double>(inv_std[f]), -5.0, 5.0)
                : 0.0;
        EXPECT_NEAR(y[r * n + f], want, 1e-5);
      }
  }
}

TEST(NnKernels, NormalizeObsMaskedRowsIgnoreGarbage) {
  const int n = 13;
  std::vector<float> x(2 * n, 1.0f);
  for (int f = 0; f < n; ++f) x[n + f] = NAN;
  std::vector<float> mean(n, 0.0f), inv(n, 1.0f), mask = {1.0f, 0.0f}, y(2 * n);
  kernels::normalize_obs(x.data(), mean.data(), inv.data(), mask.data(), 2, n, y.data());
  for (int f = 0; f < n; ++f) {
    EXPECT_EQ(y[f], 1.0f);
    EXPECT_EQ(y[n + f], 0.0f);
  }
}

TEST(NnKernels, BiasActMatchesScalar) {
  for (int n = 0; n <= max_n(); ++n) {
    for (Activation act : {Activation::kNone, Activation::kRelu}) {
      auto y = random_vector(n, 50 + n);
      auto ys = y;
      const auto b = random_vector(n, 60 + n);
      kernels::bias_act(y.data(), b.data(), act, n);
      kernels::bias_act_scalar(ys.data(), b.data(), act, n);
      EXPECT_TRUE(same_bits(y, ys));
      for (int i = 0; i < n; ++i) EXPECT_GE(y[i], act == Activation::kRelu ? 0.0f : -3.0f);
    }
  }
}

// Plain double softmax with the spec's masking.
std::vector<double> reference_softmax(const std::vector<float>& l, const std::vector<float>& m,
                                      double scale) {
  const size_t n = l.size();
  std::vector<double> z(n), p(n);
  double mx = -INFINITY;
  for (size_t i = 0; i < n; ++i) {
    z[i] = l[i] * scale - (1.0 - m[i]) * 1e10;
    mx = std::max(mx, z[i]);
  }
  double s = 0.0;
  for (size_t i = 0; i < n; ++i) {
    p[i] = std::exp(z[i] - mx) * m[i];
    s += p[i];
  }
  for (size_t i = 0; i < n; ++i) p[i] = p[i] / (s + 1e-10) * m[i];
  return p;
}

TEST(NnKernels, MaskedSoftmaxMatchesScalarAndFormula) {
  for (int n = 0; n <= max_n(); ++n) {
    const auto l = random_vector(n, 70 + n, -8.0f, 8.0f);
    auto m = random_mask(n, 80 + n);
    if (n > 0) m[n / 2] = 1.0f;
    std::vector<float> p(n), ps(n);
    kernels::masked_softmax(l.data(), m.data(), 0.7f, n, p.data());
    kernels::masked_softmax_scalar(l.data(), m.data(), 0.7f, n, ps.data());
    EXPECT_TRUE(same_bits(p, ps)) << "n = " << n;
    const auto want = reference_softmax(l, m, 0.7);
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
      EXPECT_NEAR(p[i], want[i], 1e-6);
      if (m[i] == 0.0f) {
        EXPECT_EQ(p[i], 0.0f);
      }
      sum += p[i];
    }
    if (n > 0) {
      EXPECT_NEAR(sum, 1.0, 1e-5);
    }
    // Backward: scalar equality and the analytic formula against finite differences of the reference.
    const auto dp = random_vector(n, 90 + n);
    std::vector<float> dl(n), dls(n);
    kernels::masked_softmax_backward(p.data(), dp.data(), 0.7f, n, dl.data());
    kernels::masked_softmax_backward_scalar(p.data(), dp.data(), 0.7f, n, dls.data());
    EXPECT_TRUE(same_bits(dl, dls));
    for (int i = 0; i < n; ++i) {
      if (m[i] == 0.0f) continue;
      auto lp = l, lm = l;
      lp[i] += 1e-3f;
      lm[i] -= 1e-3f;
      const auto pp = reference_softmax(lp, m, 0.7), pm = reference_softmax(lm, m, 0.7);
      double fd = 0.0;
      for (int j = 0; j < n; ++j) fd += dp[j] * (pp[j] - pm[j]) / (lp[i] - static_cast<double>(lm[i]));
      EXPECT_NEAR(dl[i], fd, 1e-4);
    }
  }
}

TEST(NnKernels, MaskedSoftmaxAllMaskedGivesZeros) {
  const std::vector<float> l = {1.0f, 2.0f, 3.0f}, m = {0.0f, 0.0f, 0.0f};
  std::vector<float> p(3, 9.0f);
  kernels::masked_softmax(l.data(), m.data(), 1.0f, 3, p.data());
  for (float v : p) EXPECT_EQ(v, 0.0f);
}

TEST(NnKernels, ActLayerNormMatchesScalarAndFormula) {
  for (int n = 0; n <= max_n(); ++n) {
    for (Activation act : {Activation::kNone, Activation::kRelu}) {
      const auto z = random_vector(n, 100 + n, -3.0f, 3.0f);
      const auto pre = random_vector(n, 110 + n);
      const auto gain = random_vector(n, 120 + n, 0.5f, 1.5f);
      const auto bias = random_vector(n, 130 + n);
      std::vector<float> a(n), as(n), y(n), ys(n), st(2), sts(2);
      kernels::act_layer_norm(z.data(), pre.data(), act, gain.data(), bias.data(), n, a.data(), y.data(),
                              st.data());
      kernels::act_layer_norm_scalar(z.data(), pre.data(), act, gain.data(), bias.data(), n, as.data(),
                                     ys.data(), sts.data());
      EXPECT_TRUE(same_bits(a, as) && same_bits(y, ys) && same_bits(st, sts)) << "n = " << n;
      double mean = 0.0, var = 0.0;
      std::vector<double> ad(n);
      for (int i = 0; i < n; ++i) {
        ad[i] = static_cast<double>(z[i]) + pre[i];
        if (act == Activation::kRelu) ad[i] = std::max(ad[i], 0.0);
        mean += ad[i] / n;
      }
      for (int i = 0; i < n; ++i) var += (ad[i] - mean) * (ad[i] - mean) / n;
      for (int i = 0; i < n; ++i) {
        const double want = var > 0.0 ? (ad[i] - mean) / std::sqrt(var + 1e-12) * gain[i] + bias[i] : bias[i];
        EXPECT_NEAR(y[i], want, 2e-5) << "n = " << n;
      }
      // Backward, vector vs scalar (accumulating into dgain/dbias).
      const auto dy = random_vector(n, 140 + n);
      std::vector<float> dg(n, 0.5f), dgs(n, 0.5f), db(n, 0.25f), dbs(n, 0.25f), dz(n), dzs(n);
      kernels::act_layer_norm_backward(a.data(), st.data(), gain.data(), dy.data(), act, n, dg.data(),
                                       db.data(), dz.data());
      kernels::act_layer_norm_backward_scalar(a.data(), st.data(), gain.data(), dy.data(), act, n, dgs.data(),
                                              dbs.data(), dzs.data());
      EXPECT_TRUE(same_bits(dg, dgs) && same_bits(db, dbs) && same_bits(dz, dzs)) << "n = " << n;
    }
  }
}

// The row-block form of the forward pass (its rows' sums reduced together) equals the scalar single-row path
// row by row, bit for bit: every width around the vector (the tails), the widths of the networks, block sizes
// around kNormRows, both activations, with and without a bias before the norm. Inputs of very different
// scales per element make a change of summation order visible.
// f(first, count) for blocks of at most kernels::kNormRows rows, in order.
template <class F>
void rows_in_blocks(int rows, F&& f) {
  for (int r0 = 0; r0 < rows; r0 += kernels::kNormRows) f(r0, std::min(kernels::kNormRows, rows - r0));
}

TEST(NnKernels, LayerNormRowBlocksEqualSingleRowsBitForBit) {
  std::vector<int> widths;
  for (int n = 0; n <= max_n(); ++n) widths.push_back(n);
  for (int n : {64, 100, 128, 256}) widths.push_back(n);
  for (int n : widths) {
    for (int count : {1, 2, 7, kernels::kNormRows, kernels::kNormRows + 1, 3 * kernels::kNormRows + 5}) {
      for (Activation act : {Activation::kNone, Activation::kRelu}) {
        for (bool with_pre : {false, true}) {
          const size_t len = static_cast<size_t>(count) * n;
          auto z = random_vector(static_cast<int>(len), 300 + n + count, -3.0f, 3.0f);
          for (size_t i = 0; i < len; ++i) z[i] *= std::ldexp(1.0f, static_cast<int>(i % 23) - 11);
          const auto pre = random_vector(n, 310 + n);
          const auto gain = random_vector(n, 320 + n, 0.5f, 1.5f);
          const auto bias = random_vector(n, 330 + n);
          const float* pre_bias = with_pre ? pre.data() : nullptr;
          const bool plain = !with_pre && act == Activation::kNone;
          std::vector<float> a(len), y(len), st(2 * count), as(len), ys(len), sts(2 * count);
          std::vector<const float*> zr(count);
          std::vector<float*> ar(count), yr(count);
          for (int r = 0; r < count; ++r) {
            const size_t o = static_cast<size_t>(r) * n;
            zr[r] = z.data() + o, ar[r] = a.data() + o, yr[r] = y.data() + o;
            kernels::act_layer_norm_scalar(z.data() + o, pre_bias, act, gain.data(), bias.data(), n,
                                           as.data() + o, ys.data() + o, sts.data() + 2 * r);
          }
          if (plain) std::fill(ar.begin(), ar.end(), nullptr);
          rows_in_blocks(count, [&](int r0, int c) {
            kernels::act_layer_norm_rows(c, zr.data() + r0, pre_bias, act, gain.data(), bias.data(), n,
                                         ar.data() + r0, yr.data() + r0, st.data() + 2 * r0);
          });
          const std::string where = "n = " + std::to_string(n) + ", rows = " + std::to_string(count) +
                                    ", relu = " + std::to_string(act == Activation::kRelu) +
                                    ", pre-bias = " + std::to_string(with_pre);
          EXPECT_TRUE(same_bits(st, sts)) << where;
          EXPECT_TRUE(same_bits(y, ys)) << where;
          if (!plain) {
            EXPECT_TRUE(same_bits(a, as)) << where;
          }
          if (!plain) {  // In place: the activations written over z, as the entity network runs it.
            std::vector<float> za = z, yi(len), sti(2 * count);
            std::vector<float*> zar(count), yir(count);
            for (int r = 0; r < count; ++r) zar[r] = za.data() + static_cast<size_t>(r) * n;
            for (int r = 0; r < count; ++r) yir[r] = yi.data() + static_cast<size_t>(r) * n;
            std::vector<const float*> zac(zar.begin(), zar.end());
            rows_in_blocks(count, [&](int r0, int c) {
              kernels::act_layer_norm_rows(c, zac.data() + r0, pre_bias, act, gain.data(), bias.data(), n,
                                           zar.data() + r0, yir.data() + r0, sti.data() + 2 * r0);
            });
            EXPECT_TRUE(same_bits(za, as) && same_bits(yi, ys) && same_bits(sti, sts))
                << where << ", in place";
          }
        }
      }
    }
  }
}

// The packed small-row product: every row count around the register tile, column counts around the panel
// width (full panels, vectors and single columns of the narrow one), both packings; vector and scalar paths
// equal bit for bit, both equal the plain fma chain over k, and a row's result does not depend on the rows
// beside it.
TEST(NnKernels, PackedGemmMatchesScalarAndFmaChain) {
  const int w = kernels::simd_width();
  for (const int n_out : {1, w - 1, w, 4 * w, 4 * w + w + 3, 9 * w + 1})
    for (const int k_in : {1, 7, 33})
      for (const bool transpose : {false, true}) {
        const int rows = 13;  // > 2 tiles of 6 (AVX-512) or 3 (AVX2) rows, and a tail
        const auto x = random_vector(size_t(rows) * k_in, 31);
        // w: [k_in, n_out], or [n_out, k_in] when packed transposed.
        const auto wv = random_vector(size_t(k_in) * n_out, 32);
        auto b = [&](int k, int n) {
          return transpose ? wv[size_t(n) * k_in + k] : wv[size_t(k) * n_out + n];
        };
        std::vector<float> packed(kernels::gemm_packed_floats(k_in, n_out));
        kernels::gemm_pack(wv.data(), transpose ? k_in : n_out, k_in, n_out, transpose, packed.data());
        const auto y0 = random_vector(size_t(rows) * n_out, 33);
        for (int m = 1; m <= rows; ++m) {
          std::vector<float> yv(y0.begin(), y0.begin() + size_t(m) * n_out), ys = yv;
          kernels::gemm_acc_packed(x.data(), k_in, packed.data(), m, k_in, n_out, yv.data(), n_out);
          kernels::gemm_acc_packed_scalar(x.data(), k_in, packed.data(), m, k_in, n_out, ys.data(), n_out);
          ASSERT_TRUE(same_bits(yv, ys)) << "rows " << m << ", n " << n_out << ", k " << k_in;
          for (int r = 0; r < m; ++r)
            for (int n = 0; n < n_out; ++n) {
              float acc = y0[size_t(r) * n_out + n];
              for (int k = 0; k < k_in; ++k) acc = std::fma(x[size_t(r) * k_in + k], b(k, n), acc);
              ASSERT_EQ(acc, yv[size_t(r) * n_out + n]) << "row " << r << " of " << m << ", column " << n;
            }
        }
      }
}

TEST(NnKernels, LstmCellMatchesScalarAndFormula) {
  // Every tail length, and rows of several vectors (the vector loop computes one vector's gates ahead).
  std::vector<int> units;
  for (int u = 0; u <= max_n(); ++u) units.push_back(u);
  for (int u : {64, 5 * kernels::simd_width() + 3, 128, 256}) units.push_back(u);
  for (int u : units) {
    const auto g = random_vector(4 * u, 150 + u, -3.0f, 3.0f);
    const auto c_prev = random_vector(u, 160 + u, -2.0f, 2.0f);
    std::vector<float> gates(4 * u), gs(4 * u), c(u), cs(u), tc(u), tcs(u), h(u), hs(u);
    kernels::lstm_cell(g.data(), c_prev.data(), u, gates.data(), c.data(), tc.data(), h.data());
    kernels::lstm_cell_scalar(g.data(), c_prev.data(), u, gs.data(), cs.data(), tcs.data(), hs.data());
    EXPECT_TRUE(same_bits(gates, gs) && same_bits(c, cs) && same_bits(tc, tcs) && same_bits(h, hs))
        << "u = " << u;
    auto sig = [](double x) { return 1.0 / (1.0 + std::exp(-x)); };
    for (int k = 0; k < u; ++k) {
      const double cn = c_prev[k] * sig(g[2 * u + k] + 1.0) + sig(g[k]) * std::tanh(g[u + k]);
      EXPECT_NEAR(c[k], cn, 1e-6);
      EXPECT_NEAR(h[k], std::tanh(cn) * sig(g[3 * u + k]), 1e-6);
    }
    // In place (gates aliasing g) gives the same.
    auto g2 = g;
    std::vector<float> c2(u), tc2(u), h2(u);
    kernels::lstm_cell(g2.data(), c_prev.data(), u, g2.data(), c2.data(), tc2.data(), h2.data());
    EXPECT_TRUE(same_bits(g2, gates) && same_bits(c2, c) && same_bits(tc2, tc) && same_bits(h2, h))
        << "u = " << u;
    const auto dh = random_vector(u, 170 + u);
    const auto dc = random_vector(u, 180 + u);
    std::vector<float> dg(4 * u), dgs(4 * u), dcp(u), dcps(u);
    kernels::lstm_cell_backward(gates.data(), c_prev.data(), tc.data(), dh.data(), dc.data(), u, dg.data(),
                                dcp.data());
    kernels::lstm_cell_backward_scalar(gates.data(), c_prev.data(), tc.data(), dh.data(), dc.data(), u,
                                       dgs.data(), dcps.data());
    EXPECT_TRUE(same_bits(dg, dgs) && same_bits(dcp, dcps)) << "u = " << u;
  }
}

}  // namespace
}  // namespace hns::nn
