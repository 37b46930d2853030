// Every layer's backward pass against central differences of an independent double-precision reference of its
// forward pass (which also checks the float forward), plus the masking and LSTM-stepping properties users
// rely on.
#include "nn/layers.hpp"
#include "nn/kernels.hpp"
#include "nn/simd.hpp"

#include "test_util.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <vector>

namespace hns::nn {
namespace {

using testing::expect_gradient_matches;
using testing::random_mask;
using testing::random_vector;
using testing::to_double;

// Parameters filled with random values (gains near 1) so every term of the forward pass is exercised.
void randomize(ParamStore& store, uint64_t seed) {
  store.init(seed);
  auto r = random_vector(store.buffer_floats(), seed + 1, -0.5f, 0.5f);
  for (const ParamSlice& s : store.layout().slices()) {
    const bool gain = s.name.find("gain") != std::string::npos;
    for (size_t i = 0; i < s.size(); ++i)
      store.values()[s.offset + i] = (gain ? 1.0f : 0.0f) + r[s.offset + i];
  }
}

size_t off(const ParamStore& store, const std::string& name) {
  return store.layout().find(name)->offset;
}

double weighted_sum(const std::vector<double>& y, const std::vector<float>& w) {
  double s = 0.0;
  for (size_t i = 0; i < y.size(); ++i) s += y[i] * w[i];
  return s;
}

void expect_forward_close(const std::vector<float>& y, const std::vector<double>& ref, double tol,
                          const std::string& what) {
  ASSERT_EQ(y.size(), ref.size());
  double worst = 0.0;
  for (size_t i = 0; i < y.size(); ++i)
    worst = std::max(worst, std::fabs(y[i] - ref[i]) / (1.0 + std::fabs(ref[i])));
  EXPECT_LE(worst, tol) << what << " forward differs from the double reference";
}

std::vector<float> concat(std::vector<float> a, const float* b, size_t n) {
  a.insert(a.end(), b, b + n);
  return a;
}
std::vector<double> concat(std::vector<double> a, const float* b, size_t n) {
  a.insert(a.end(), b, b + n);
  return a;
}

// ---- double-precision references ----

std::vector<double> ref_dense(const double* x, const double* w, const double* b, int rows, int in, int out,
                              bool relu) {
  std::vector<double> y(static_cast<size_t>(rows) * out);
  for (int r = 0; r < rows; ++r)
    for (int o = 0; o < out; ++o) {
      double s = b[o];
      for (int i = 0; i < in; ++i) s += x[r * in + i] * w[i * out + o];
      y[r * out + o] = relu ? std::max(s, 0.0) : s;
    }
  return y;
}

std::vector<double> ref_layer_norm(const double* x, const double* g, const double* b, int rows, int n) {
  std::vector<double> y(static_cast<size_t>(rows) * n);
  for (int r = 0; r < rows; ++r) {
    double mean = 0.0, var = 0.0;
    for (int i = 0; i < n; ++i) mean += x[r * n + i] / n;
    for (int i = 0; i < n; ++i) var += (x[r * n + i] - mean) * (x[r * n + i] - mean) / n;
    for (int i = 0; i < n; ++i) y[r * n + i] = (x[r * n + i] - mean) / std::sqrt(var + 1e-12) * g[i] + b[i];
  }
  return y;
}

TEST(NnLayers, DenseBackwardMatchesFiniteDifferences) {
  for (Activation act : {Activation::kNone, Activation::kRelu}) {
    const int rows = 6, in = 7, out = 5;
    ParamLayout layout;
    Dense dense(layout, "d", in, out, act);
    ParamStore store(layout);
    randomize(store, 1);
    const auto x = random_vector(rows * in, 2);
    const auto w = random_vector(rows * out, 3);
    std::vector<float> y(rows * out), dy = w, dx(rows * in);
    dense.forward(store.values(), CMat(x.data(), rows, in), Mat(y.data(), rows, out));
    dense.backward(store.values(), store.grads(), CMat(x.data(), rows, in), CMat(y.data(), rows, out),
                   Mat(dy.data(), rows, out), Mat(dx.data(), rows, in), false);
    const size_t nx = x.size(), wo = off(store, "d/w"), bo = off(store, "d/b");
    auto forward = [&](const std::vector<double>& v) {
      const double* p = v.data() + nx;
      return ref_dense(v.data(), p + wo, p + bo, rows, in, out, act == Activation::kRelu);
    };
    const auto point = concat(to_double(x), store.values(), store.buffer_floats());
    expect_forward_close(y, forward(point), 1e-6, "dense");
    expect_gradient_matches([&](const std::vector<double>& v) { return weighted_sum(forward(v), w); }, point,
                            concat(dx, store.grads(), store.buffer_floats()), 1e-4, "dense");
  }
}

TEST(NnLayers, LayerNormBackwardMatchesFiniteDifferences) {
  const int rows = 5, n = 19;
  ParamLayout layout;
  LayerNorm ln(layout, "ln", n);
  ParamStore store(layout);
  randomize(store, 4);
  const auto x = random_vector(rows * n, 5, -2.0f, 2.0f);
  const auto w = random_vector(rows * n, 6);
  std::vector<float> y(rows * n), stats(2 * rows), dx(rows * n);
  ln.forward(store.values(), CMat(x.data(), rows, n), Mat(y.data(), rows, n), stats.data());
  ln.backward(store.values(), store.grads(), CMat(x.data(), rows, n), stats.data(), CMat(w.data(), rows, n),
              Mat(dx.data(), rows, n));
  const size_t nx = x.size(), go = off(store, "ln/gain"), bo = off(store, "ln/bias");
  auto forward = [&](const std::vector<double>& v) {
    const double* p = v.data() + nx;
    return ref_layer_norm(v.data(), p + go, p + bo, rows, n);
  };
  const auto point = concat(to_double(x), store.values(), store.buffer_floats());
  expect_forward_close(y, forward(point), 1e-5, "layer norm");
  expect_gradient_matches([&](const std::vector<double>& v) { return weighted_sum(forward(v), w); }, point,
                          concat(dx, store.grads(), store.buffer_floats()), 2e-4, "layer norm");
}

// The layer's forward passes take their rows in blocks (kernels::act_layer_norm_rows); across block
// boundaries, through forward_scatter's row map and with the fused form in place (its activations written
// over its input, as the entity network calls it), every row equals the single-row kernel bit for bit.
TEST(NnLayers, LayerNormForwardsEqualTheSingleRowKernelAcrossBlocks) {
  const int rows = 2 * kernels::kNormRows + 5, n = 64;
  ParamLayout layout;
  LayerNorm ln(layout, "ln", n);
  const size_t pre_off = layout.add_vector("pre", n, Init::kZeros);
  ParamStore store(layout);
  randomize(store, 11);
  const float* gain = store.values() + off(store, "ln/gain");
  const float* bias = store.values() + off(store, "ln/bias");
  const float* pre = store.values() + pre_off;
  const auto x = random_vector(rows * n, 12, -2.0f, 2.0f);
  std::vector<int32_t> y_rows(rows);
  for (int r = 0; r < rows; ++r) y_rows[r] = (r * 7 + 3) % rows;  // a permutation (7 and 37 coprime)
  std::vector<float> y(rows * n), ys(rows * n), st(2 * rows), y_ref(rows * n), a_ref(rows * n),
      st_ref(2 * rows);
  auto same = [](const std::vector<float>& u, const std::vector<float>& v) {
    return std::memcmp(u.data(), v.data(), u.size() * sizeof(float)) == 0;
  };
  for (int r = 0; r < rows; ++r)
    kernels::act_layer_norm(x.data() + r * n, nullptr, Activation::kNone, gain, bias, n, nullptr,
                            y_ref.data() + r * n, st_ref.data() + 2 * r);
  ln.forward(store.values(), CMat(x.data(), rows, n), Mat(y.data(), rows, n), st.data());
  EXPECT_TRUE(same(y, y_ref) && same(st, st_ref)) << "forward";
  ln.forward_scatter(store.values(), CMat(x.data(), rows, n), y_rows.data(), Mat(ys.data(), rows, n),
                     st.data());
  bool scattered = same(st, st_ref);
  for (int r = 0; r < rows; ++r)
    scattered =
        scattered && std::memcmp(ys.data() + y_rows[r] * n, y_ref.data() + r * n, n * sizeof(float)) == 0;
  EXPECT_TRUE(scattered) << "forward_scatter";
  for (int r = 0; r < rows; ++r)
    kernels::act_layer_norm(x.data() + r * n, pre, Activation::kRelu, gain, bias, n, a_ref.data() + r * n,
                            y_ref.data() + r * n, st_ref.data() + 2 * r);
  std::vector<float> za = x;  // activations written over the input
  ln.forward_fused(store.values(), CMat(za.data(), rows, n), pre, Activation::kRelu, Mat(za.data(), rows, n),
                   Mat(y.data(), rows, n), st.data());
  EXPECT_TRUE(same(za, a_ref) && same(y, y_ref) && same(st, st_ref)) << "forward_fused in place";
}

TEST(NnLayers, FusedBiasReluLayerNormBackwardMatchesFiniteDifferences) {
  const int rows = 4, n = 11;
  ParamLayout layout;
  LayerNorm ln(layout, "ln", n);
  const size_t pre_off = layout.add_vector("pre", n, Init::kZeros);
  ParamStore store(layout);
  randomize(store, 7);
  const auto z = random_vector(rows * n, 8, -1.0f, 1.0f);
  const auto w = random_vector(rows * n, 9);
  std::vector<float> a(rows * n), y(rows * n), stats(2 * rows), dz(rows * n);
  ln.forward_fused(store.values(), CMat(z.data(), rows, n), store.values() + pre_off, Activation::kRelu,
                   Mat(a.data(), rows, n), Mat(y.data(), rows, n), stats.data());
  ln.backward_fused(store.values(), store.grads(), CMat(a.data(), rows, n), stats.data(), Activation::kRelu,
                    CMat(w.data(), rows, n), Mat(dz.data(), rows, n), store.grads() + pre_off);
  const size_t nz = z.size(), go = off(store, "ln/gain"), bo = off(store, "ln/bias");
  auto forward = [&](const std::vector<double>& v) {
    const double* p = v.data() + nz;
    std::vector<double> act(nz);
    for (int r = 0; r < rows; ++r)
      for (int i = 0; i < n; ++i) act[r * n + i] = std::max(v[r * n + i] + p[pre_off + i], 0.0);
    return ref_layer_norm(act.data(), p + go, p + bo, rows, n);
  };
  const auto point = concat(to_double(z), store.values(), store.buffer_floats());
  expect_forward_close(y, forward(point), 1e-5, "relu + layer norm");
  expect_gradient_matches([&](const std::vector<double>& v) { return weighted_sum(forward(v), w); }, point,
                          concat(dz, store.grads(), store.buffer_floats()), 2e-4, "relu + layer norm");
}

TEST(NnLayers, CircConvBackwardMatchesFiniteDifferences) {
  const int rows = 3, length = 30, filters = 9, kernel = 3;
  ParamLayout layout;
  CircConv1d conv(layout, "c", length, 1, filters, kernel);
  ParamStore store(layout);
  randomize(store, 10);
  const auto x = random_vector(rows * length, 11, 0.0f, 6.0f);
  const auto w = random_vector(rows * length * filters, 12);
  std::vector<float> y(w.size()), dy = w;
  conv.forward(store.values(), CMat(x.data(), rows, length), Mat(y.data(), rows, length * filters));
  conv.backward(store.values(), store.grads(), CMat(x.data(), rows, length),
                CMat(y.data(), rows, length * filters), Mat(dy.data(), rows, length * filters));
  const size_t wo = off(store, "c/w"), bo = off(store, "c/b");
  auto forward = [&](const std::vector<double>& p) {
    std::vector<double> out(w.size());
    for (int r = 0; r < rows; ++r)
      for (int pos = 0; pos < length; ++pos)
        for (int f = 0; f < filters; ++f) {
          // Circular padding [x29, x0 .. x29, x0], then a valid convolution.
          double s = p[bo + f];
          for (int k = 0; k < kernel; ++k)
            s += x[r * length + (pos + k - 1 + length) % length] * p[wo + k * filters + f];
          out[(r * length + pos) * filters + f] = std::max(s, 0.0);
        }
    return out;
  };
  const auto point = concat(std::vector<double>{}, store.values(), store.buffer_floats());
  expect_forward_close(y, forward(point), 1e-6, "circular conv");
  expect_gradient_matches([&](const std::vector<double>& v) { return weighted_sum(forward(v), w); }, point,
                          concat(std::vector<float>{}, store.grads(), store.buffer_floats()), 1e-4,
                          "circular conv");
  // Wrap-around: position 0 sees ray 29 through kernel tap 0.
  std::vector<float> spike(length, 0.0f), ys(length * filters);
  spike[29] = 1.0f;
  conv.forward(store.values(), CMat(spike.data(), 1, length), Mat(ys.data(), 1, length * filters));
  for (int f = 0; f < filters; ++f)
    EXPECT_FLOAT_EQ(ys[f], std::max(store.values()[bo + f] + store.values()[wo + f], 0.0f));
}

// The conv's arithmetic, element by element, as CircConv1d documents it: each output is b[f], then an fma per
// tap (k, then channel c) in order, then the ReLU; each parameter's gradient is summed in simd::kWidth lanes
// (lane l: positions p = l mod the width, rows in order, then positions; zero past the length) and the lanes
// added in order. Forms of AVX-512 builds and of the general pass must both give these bits.
TEST(NnLayers, CircConvEqualsItsElementwiseDefinitionBitForBit) {
  struct Shape {
    int length, in_ch, filters, kernel;
  };
  const int width = simd::kWidth;
  // The models' shape and others of one channel within the AVX-512 output-order passes' limits (extended
  // input and weights at most 32 floats, at most 16 filters), then just past each limit and two channels
  // (the general pass).
  for (const Shape s :
       {Shape{30, 1, 9, 3}, Shape{7, 1, 4, 3}, Shape{16, 1, 6, 5}, Shape{28, 1, 6, 5}, Shape{17, 1, 16, 1},
        Shape{31, 1, 9, 3}, Shape{30, 1, 11, 3}, Shape{10, 1, 17, 1}, Shape{12, 2, 5, 3}}) {
    const std::string where = "length " + std::to_string(s.length) + " in " + std::to_string(s.in_ch) +
                              " filters " + std::to_string(s.filters) + " kernel " + std::to_string(s.kernel);
    const int rows = 5, outs = s.length * s.filters, taps = s.kernel * s.in_ch;
    ParamLayout layout;
    CircConv1d conv(layout, "c", s.length, s.in_ch, s.filters, s.kernel);
    ParamStore store(layout);
    randomize(store, 20);
    const float* w = store.values() + off(store, "c/w");
    const float* b = store.values() + off(store, "c/b");
    const auto x = random_vector(rows * s.length * s.in_ch, 21);
    const auto dy0 = random_vector(rows * outs, 22);
    std::vector<float> y(size_t(rows) * outs), dy = dy0;
    conv.forward(store.values(), CMat(x.data(), rows, s.length * s.in_ch), Mat(y.data(), rows, outs));
    conv.backward(store.values(), store.grads(), CMat(x.data(), rows, s.length * s.in_ch),
                  CMat(y.data(), rows, outs), Mat(dy.data(), rows, outs));
    // xe(r, c, j): the circularly extended input, zero from length + kernel - 1 on.
    auto xe = [&](int r, int c, int j) {
      if (j >= s.length + s.kernel - 1) return 0.0f;
      const int src = (j - s.kernel / 2 + s.length) % s.length;
      return x[size_t(r) * s.length * s.in_ch + size_t(src) * s.in_ch + c];
    };
    const int padded = (s.length + width - 1) / width * width;
    std::vector<float> lanes(size_t(taps + 1) * s.filters * width, 0.0f);
    for (int r = 0; r < rows; ++r)
      for (int f = 0; f < s.filters; ++f)
        for (int p = 0; p < padded; ++p) {
          const int l = p % width;
          float d = 0.0f;
          if (p < s.length) {
            float z = b[f];
            for (int k = 0; k < s.kernel; ++k)
              for (int c = 0; c < s.in_ch; ++c)
                z = std::fma(w[(k * s.in_ch + c) * s.filters + f], xe(r, c, p + k), z);
            const size_t i = size_t(r) * outs + size_t(p) * s.filters + f;
            const float want = std::max(z, 0.0f);
            ASSERT_EQ(std::bit_cast<uint32_t>(y[i]), std::bit_cast<uint32_t>(want))
                << where << " forward at " << i;
            d = y[i] > 0.0f ? dy0[i] : 0.0f;
            ASSERT_EQ(std::bit_cast<uint32_t>(dy[i]), std::bit_cast<uint32_t>(d))
                << where << " masked dy at " << i;
          }
          float& lb = lanes[(size_t(taps) * s.filters + f) * width + l];
          lb = lb + d;
          for (int k = 0; k < s.kernel; ++k)
            for (int c = 0; c < s.in_ch; ++c) {
              float& lw = lanes[(size_t(k * s.in_ch + c) * s.filters + f) * width + l];
              lw = std::fma(d, xe(r, c, p + k), lw);
            }
        }
    const float* gw = store.grads() + off(store, "c/w");
    const float* gb = store.grads() + off(store, "c/b");
    for (int i = 0; i < (taps + 1) * s.filters; ++i) {
      float sum = 0.0f;
      for (int l = 0; l < width; ++l) sum += lanes[size_t(i) * width + l];
      const float got = i < taps * s.filters ? gw[i] : gb[i - taps * s.filters];
      ASSERT_EQ(std::bit_cast<uint32_t>(got), std::bit_cast<uint32_t>(sum)) << where << " gradient " << i;
    }
  }
}

TEST(NnLayers, EntityEmbeddingBackwardMatchesFiniteDifferences) {
  const int rows = 4, m = 9, f = 5, d = 6, count = 3, entities = 5, first = 1;
  ParamLayout layout;
  EntityEmbedding emb(layout, "e", m, f, d);
  ParamStore store(layout);
  randomize(store, 13);
  const auto main = random_vector(rows * m, 14);
  const auto ent = random_vector(rows * count * f, 15);
  const auto w = random_vector(rows * entities * d, 16);
  std::vector<float> x(rows * entities * d, 0.0f), scratch(rows * d), scratch_ent(rows * count * d),
      dmain(rows * m);
  const EntitySlots slots{x.data(), rows, entities, d, first, count};
  emb.forward(store.values(), CMat(main.data(), rows, m), CMat(ent.data(), rows * count, f), slots,
              Mat(scratch.data(), rows, d));
  std::vector<float> dx = w;
  emb.backward(store.values(), store.grads(), CMat(main.data(), rows, m), CMat(ent.data(), rows * count, f),
               slots, {dx.data(), rows, entities, d, first, count}, Mat(scratch.data(), rows, d),
               Mat(scratch_ent.data(), rows * count, d), Mat(dmain.data(), rows, m));
  const size_t nm = main.size(), wo = off(store, "e/w"), bo = off(store, "e/b");
  // Reference: relu([main, ent] W + b) written into slots [first, first + count); other slots stay 0.
  auto forward = [&](const std::vector<double>& v) {
    const double* p = v.data() + nm;
    std::vector<double> out(x.size(), 0.0);
    for (int r = 0; r < rows; ++r)
      for (int e = 0; e < count; ++e)
        for (int o = 0; o < d; ++o) {
          double s = p[bo + o];
          for (int i = 0; i < m; ++i) s += v[r * m + i] * p[wo + i * d + o];
          for (int i = 0; i < f; ++i) s += ent[(r * count + e) * f + i] * p[wo + (m + i) * d + o];
          out[(r * entities + first + e) * d + o] = std::max(s, 0.0);
        }
    return out;
  };
  const auto point = concat(to_double(main), store.values(), store.buffer_floats());
  expect_forward_close(x, forward(point), 1e-6, "entity embedding");
  expect_gradient_matches([&](const std::vector<double>& v) { return weighted_sum(forward(v), w); }, point,
                          concat(dmain, store.grads(), store.buffer_floats()), 1e-4, "entity embedding");
}

// Reference residual self-attention block (pre and post layer norm) in double.
std::vector<double> ref_attention(const double* x, const double* p, const ParamStore& s, const float* mask,
                                  int rows, int e_count, int d, int heads) {
  const int n = rows * e_count, dh = d / heads;
  const auto xn = ref_layer_norm(x, p + off(s, "a/ln_pre/gain"), p + off(s, "a/ln_pre/bias"), n, d);
  const auto qk = ref_dense(xn.data(), p + off(s, "a/qk/w"), p + off(s, "a/qk/b"), n, d, 2 * d, false);
  const auto v = ref_dense(xn.data(), p + off(s, "a/v/w"), p + off(s, "a/v/b"), n, d, d, false);
  std::vector<double> att(static_cast<size_t>(n) * d, 0.0);
  for (int r = 0; r < rows; ++r)
    for (int h = 0; h < heads; ++h)
      for (int i = 0; i < e_count; ++i) {
        std::vector<double> l(e_count);
        double mx = -INFINITY;
        for (int j = 0; j < e_count; ++j) {
          double dotp = 0.0;
          for (int c = 0; c < dh; ++c)
            dotp += qk[(r * e_count + i) * 2 * d + (h * dh + c) * 2] *
                    qk[(r * e_count + j) * 2 * d + (h * dh + c) * 2 + 1];
          l[j] = dotp / std::sqrt(static_cast<double>(dh)) - (1.0 - mask[r * e_count + j]) * 1e10;
          mx = std::max(mx, l[j]);
        }
        double sum = 0.0;
        for (int j = 0; j < e_count; ++j) {
          l[j] = std::exp(l[j] - mx) * mask[r * e_count + j];
          sum += l[j];
        }
        for (int j = 0; j < e_count; ++j) {
          const double pj = l[j] / (sum + 1e-10) * mask[r * e_count + j];
          for (int c = 0; c < dh; ++c)
            att[(r * e_count + i) * d + h * dh + c] += pj * v[(r * e_count + j) * d + h * dh + c];
        }
      }
  auto res = ref_dense(att.data(), p + off(s, "a/mlp1/w"), p + off(s, "a/mlp1/b"), n, d, d, false);
  for (size_t i = 0; i < res.size(); ++i) res[i] += x[i];
  auto out = ref_layer_norm(res.data(), p + off(s, "a/ln_post/gain"), p + off(s, "a/ln_post/bias"), n, d);
  // A masked entity is no query either: its output is 0.
  for (int i = 0; i < n; ++i)
    if (mask[i] == 0.0f)
      std::fill(out.begin() + static_cast<ptrdiff_t>(i) * d, out.begin() + (i + 1) * d, 0.0);
  return out;
}

// Small, and with more entities than two vectors of keys and a head wider than a vector (the vector paths of
// the score and p·V loops).
TEST(NnLayers, SelfAttentionBackwardMatchesFiniteDifferences) {
  struct Shape {
    int rows, e_count, d, heads;
  };
  const int wide = 2 * kernels::simd_width() + 3;
  for (const Shape& sh : {Shape{3, 5, 8, 2}, Shape{2, wide, 32, 2}}) {
    const int rows = sh.rows, e_count = sh.e_count, d = sh.d, heads = sh.heads;
    ParamLayout layout;
    SelfAttention sa(layout, "a", d, heads, true, true);
    ParamStore store(layout);
    randomize(store, 17);
    const auto x = random_vector(rows * e_count * d, 18);
    auto mask = random_mask(rows * e_count, 19, 0.6);
    for (int r = 0; r < rows; ++r) mask[r * e_count + e_count - 1] = 1.0f;  // self
    const auto w = random_vector(x.size(), 20);
    Workspace<SelfAttention::Buffers> ws(rows, e_count, d, heads);
    std::vector<float> y(x.size()), dx(x.size());
    sa.forward(store.values(), CMat(x.data(), rows * e_count, d), mask.data(), e_count, ws.bufs(),
               Mat(y.data(), rows * e_count, d));
    sa.backward(store.values(), store.grads(), CMat(x.data(), rows * e_count, d), mask.data(), e_count,
                ws.bufs(), CMat(y.data(), rows * e_count, d), CMat(w.data(), rows * e_count, d),
                Mat(dx.data(), rows * e_count, d));
    const size_t nx = x.size();
    auto forward = [&](const std::vector<double>& v) {
      return ref_attention(v.data(), v.data() + nx, store, mask.data(), rows, e_count, d, heads);
    };
    const auto point = concat(to_double(x), store.values(), store.buffer_floats());
    expect_forward_close(y, forward(point), 2e-5, "self-attention");
    expect_gradient_matches([&](const std::vector<double>& v) { return weighted_sum(forward(v), w); }, point,
                            concat(dx, store.grads(), store.buffer_floats()), 3e-4, "self-attention", 900);
  }
}

TEST(NnLayers, MaskedEntitiesChangeNothingInAttentionAndPooling) {
  const int rows = 4, e_count = 6, d = 8, heads = 2;
  ParamLayout layout;
  SelfAttention sa(layout, "a", d, heads, true, true);
  ParamStore store(layout);
  randomize(store, 21);
  auto x = random_vector(rows * e_count * d, 22);
  auto mask = random_mask(rows * e_count, 23, 0.5);
  for (int r = 0; r < rows; ++r) mask[r * e_count + e_count - 1] = 1.0f;
  Workspace<SelfAttention::Buffers> ws(rows, e_count, d, heads);
  auto run = [&](const std::vector<float>& in) {
    std::vector<float> y(in.size()), pooled(rows * d);
    sa.forward(store.values(), CMat(in.data(), rows * e_count, d), mask.data(), e_count, ws.bufs(),
               Mat(y.data(), rows * e_count, d));
    masked_mean_pool(CMat(y.data(), rows * e_count, d), mask.data(), e_count, Mat(pooled.data(), rows, d));
    return std::make_pair(y, pooled);
  };
  const auto [y0, pooled0] = run(x);
  // Scramble every masked entity's features (including huge values).
  auto x2 = x;
  int masked = 0;
  for (int i = 0; i < rows * e_count; ++i)
    if (mask[i] == 0.0f) {
      ++masked;
      for (int c = 0; c < d; ++c) x2[i * d + c] = 1e6f * static_cast<float>(c % 3 - 1) + 17.0f;
    }
  ASSERT_GT(masked, 0);
  const auto [y1, pooled1] = run(x2);
  EXPECT_EQ(0, std::memcmp(pooled0.data(), pooled1.data(), pooled0.size() * sizeof(float)));
  for (int i = 0; i < rows * e_count; ++i)
    if (mask[i] != 0.0f) {
      EXPECT_EQ(0, std::memcmp(&y0[i * d], &y1[i * d], d * sizeof(float))) << "entity " << i;
    }
  // And an unmasked entity's change does change the pool (the test can fail).
  auto x3 = x;
  x3[0] += mask[0] != 0.0f ? 1.0f : 0.0f;
  x3[(e_count - 1) * d] += 1.0f;
  const auto [y3, pooled3] = run(x3);
  EXPECT_NE(0, std::memcmp(pooled0.data(), pooled3.data(), pooled0.size() * sizeof(float)));
}

TEST(NnLayers, MaskedMeanPoolMatchesFormulaAndGradient) {
  const int rows = 3, e_count = 4, d = 5;
  const auto x = random_vector(rows * e_count * d, 24);
  auto mask = random_mask(rows * e_count, 25);
  mask[4] = mask[5] = mask[6] = mask[7] = 0.0f;  // a row with nothing visible pools to 0
  const auto w = random_vector(rows * d, 26);
  std::vector<float> y(rows * d), dx(x.size());
  masked_mean_pool(CMat(x.data(), rows * e_count, d), mask.data(), e_count, Mat(y.data(), rows, d));
  masked_mean_pool_backward(CMat(w.data(), rows, d), mask.data(), e_count, Mat(dx.data(), rows * e_count, d));
  auto forward = [&](const std::vector<double>& v) {
    std::vector<double> out(rows * d, 0.0);
    for (int r = 0; r < rows; ++r) {
      double ms = 0.0;
      for (int e = 0; e < e_count; ++e) ms += mask[r * e_count + e];
      for (int c = 0; c < d; ++c) {
        double s = 0.0;
        for (int e = 0; e < e_count; ++e) s += v[(r * e_count + e) * d + c] * mask[r * e_count + e];
        out[r * d + c] = s / (ms + 1e-5);
      }
    }
    return out;
  };
  expect_forward_close(y, forward(to_double(x)), 1e-6, "pool");
  for (int c = 0; c < d; ++c) EXPECT_EQ(y[d + c], 0.0f);
  expect_gradient_matches([&](const std::vector<double>& v) { return weighted_sum(forward(v), w); },
                          to_double(x), dx, 1e-5, "pool");
}

// Reference LSTM in double over sequence-major rows; returns every step's h.
std::vector<double> ref_lstm(const double* x, const double* w, const double* b, const float* reset,
                             const float* state_in, int seqs, int steps, int in, int u) {
  auto sig = [](double v) { return 1.0 / (1.0 + std::exp(-v)); };
  std::vector<double> out(static_cast<size_t>(seqs) * steps * u);
  for (int s = 0; s < seqs; ++s) {
    std::vector<double> c(u), h(u);
    for (int k = 0; k < u; ++k) {
      c[k] = state_in[s * 2 * u + k];
      h[k] = state_in[s * 2 * u + u + k];
    }
    for (int t = 0; t < steps; ++t) {
      const int row = s * steps + t;
      if (reset[row] != 0.0f) std::fill(c.begin(), c.end(), 0.0), std::fill(h.begin(), h.end(), 0.0);
      std::vector<double> g(4 * u);
      for (int o = 0; o < 4 * u; ++o) {
        double acc = b[o];
        for (int i = 0; i < in; ++i) acc += x[row * in + i] * w[i * 4 * u + o];
        for (int i = 0; i < u; ++i) acc += h[i] * w[(in + i) * 4 * u + o];
        g[o] = acc;
      }
      for (int k = 0; k < u; ++k) {
        c[k] = c[k] * sig(g[2 * u + k] + 1.0) + sig(g[k]) * std::tanh(g[u + k]);
        h[k] = std::tanh(c[k]) * sig(g[3 * u + k]);
        out[static_cast<size_t>(row) * u + k] = h[k];
      }
    }
  }
  return out;
}

TEST(NnLayers, LstmBackwardThroughTimeMatchesFiniteDifferences) {
  const int seqs = 3, steps = 5, in = 4, u = 6;
  ParamLayout layout;
  Lstm lstm(layout, "l", in, u);
  ParamStore store(layout);
  randomize(store, 27);
  const int rows = seqs * steps;
  const auto x = random_vector(rows * in, 28, -2.0f, 2.0f);
  const auto state = random_vector(seqs * 2 * u, 29);
  std::vector<float> reset(rows, 0.0f);
  reset[1 * steps + 2] = 1.0f;  // sequence 1 restarts at step 2
  reset[2 * steps + 0] = 1.0f;  // sequence 2 starts from zero state
  const auto w = random_vector(rows * u, 30);
  Workspace<Lstm::Buffers> ws(seqs, steps, in, u);
  std::vector<float> dx(rows * in);
  lstm.forward(store.values(), CMat(x.data(), rows, in), seqs, steps, reset.data(), state.data(), ws.bufs(),
               nullptr);
  const std::vector<float> h(ws.bufs().h, ws.bufs().h + rows * u);
  lstm.backward(store.values(), store.grads(), CMat(x.data(), rows, in), seqs, steps, reset.data(), ws.bufs(),
                CMat(w.data(), rows, u), Mat(dx.data(), rows, in));
  const size_t nx = x.size(), wo = off(store, "l/w"), bo = off(store, "l/b");
  auto forward = [&](const std::vector<double>& v) {
    const double* p = v.data() + nx;
    return ref_lstm(v.data(), p + wo, p + bo, reset.data(), state.data(), seqs, steps, in, u);
  };
  const auto point = concat(to_double(x), store.values(), store.buffer_floats());
  expect_forward_close(h, forward(point), 2e-6, "lstm");
  expect_gradient_matches([&](const std::vector<double>& v) { return weighted_sum(forward(v), w); }, point,
                          concat(dx, store.grads(), store.buffer_floats()), 2e-4, "lstm", 900);
}

TEST(NnLayers, LstmTenStepsEqualTenSingleSteps) {
  const int seqs = 4, steps = 10, in = 12, u = 16;
  ParamLayout layout;
  Lstm lstm(layout, "l", in, u);
  ParamStore store(layout);
  store.init(31);
  const int rows = seqs * steps;
  const auto x = random_vector(rows * in, 32, -2.0f, 2.0f);
  std::vector<float> reset(rows, 0.0f);
  reset[2 * steps + 6] = 1.0f;
  Workspace<Lstm::Buffers> chunk(seqs, steps, in, u);
  std::vector<float> state_chunk(seqs * 2 * u);
  lstm.forward(store.values(), CMat(x.data(), rows, in), seqs, steps, reset.data(), nullptr, chunk.bufs(),
               state_chunk.data());
  // The same sequences one step at a time, carrying the state.
  Workspace<Lstm::Buffers> single(seqs, 1, in, u);
  std::vector<float> state(seqs * 2 * u, 0.0f), xt(seqs * in), rt(seqs);
  double worst = 0.0;
  for (int t = 0; t < steps; ++t) {
    for (int s = 0; s < seqs; ++s) {
      std::memcpy(&xt[s * in], &x[(s * steps + t) * in], in * sizeof(float));
      rt[s] = reset[s * steps + t];
    }
    lstm.forward(store.values(), CMat(xt.data(), seqs, in), seqs, 1, rt.data(), state.data(), single.bufs(),
                 state.data());
    for (int s = 0; s < seqs; ++s)
      for (int k = 0; k < u; ++k)
        worst = std::max(worst, static_cast<double>(std::fabs(single.bufs().h[s * u + k] -
                                                              chunk.bufs().h[(s * steps + t) * u + k])));
  }
  EXPECT_LT(worst, 1e-6);
  for (int i = 0; i < seqs * 2 * u; ++i) EXPECT_NEAR(state[i], state_chunk[i], 1e-6);
  // The reset really cut the history: sequence 2 from step 6 equals a fresh run of its last 4 steps.
  Workspace<Lstm::Buffers> tail(1, 4, in, u);
  lstm.forward(store.values(), CMat(&x[(2 * steps + 6) * in], 4, in), 1, 4, nullptr, nullptr, tail.bufs(),
               nullptr);
  for (int k = 0; k < 4 * u; ++k)
    EXPECT_NEAR(tail.bufs().h[k], chunk.bufs().h[(2 * steps + 6) * u + k], 1e-6);
}

}  // namespace
}  // namespace hns::nn
