// Row helpers the layers share (nn/layers.cpp, nn/attention.cpp): small vector loops over float rows and the
// dense product with its bias as the starting value. Internal to the nn library.
#pragma once

#include "nn/layers.hpp"
#include "nn/products.hpp"
#include "nn/simd.hpp"

#include <cstring>

namespace hns::nn::rows {

using simd::load;
using simd::store;

// out[0, n) += in[0, n).
inline void add_row(float* out, const float* in, int n) {
  simd::for_each<true>(n, [&](auto tag, int i) {
    using F = decltype(tag);
    store(out + i, load<F>(out + i) + load<F>(in + i));
  });
}

// y[0, n) = x[0, n) where mask[0, n) > 0, else 0 (a ReLU's backward: mask is its output). y may alias x.
inline void relu_mask(const float* x, const float* mask, int n, float* y) {
  simd::for_each<true>(n, [&](auto tag, int i) {
    using F = decltype(tag);
    store(y + i, simd::select(load<F>(mask + i) > F(0.0f), load<F>(x + i), F(0.0f)));
  });
}

// y[0, n) *= a.
inline void scale_row(float* y, float a, int n) {
  simd::for_each<true>(n, [&](auto tag, int i) {
    using F = decltype(tag);
    store(y + i, load<F>(y + i) * F(a));
  });
}

// Column sums of dz accumulated into g (rows in order).
inline void add_col_sums(float* g, CMat dz) {
  for (int r = 0; r < dz.rows; ++r) add_row(g, dz.row(r), dz.cols);
}

inline void zero_mat(Mat m) {
  for (int r = 0; r < m.rows; ++r) std::memset(m.row(r), 0, sizeof(float) * m.cols);
}

// y[0, n) += a * x[0, n) (fused multiply-add).
inline void axpy(float a, const float* x, float* y, int n) {
  simd::for_each<true>(n, [&](auto tag, int i) {
    using F = decltype(tag);
    store(y + i, simd::fma(F(a), load<F>(x + i), load<F>(y + i)));
  });
}

// y = act(x w + b), w [x.cols, y.cols] (product matrix id of p): the bias is the product's starting value (no
// zeroing pass, no separate bias pass), the activation one pass over y while it is in cache.
inline void dense_forward(const Weights& p, int id, const SharedRows& x, const float* w, const float* b,
                          Activation act, Mat y) {
  matmul_bias(p, id, w, b, x, y);
  if (act != Activation::kNone)
    for (int r = 0; r < y.rows; ++r) kernels::bias_act(y.row(r), nullptr, act, y.cols);
}

}  // namespace hns::nn::rows
