#include "nn/layers.hpp"

#include "nn/row_ops.hpp"
#include "nn/simd.hpp"
#include "nn/transpose16.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace hns::nn {

using namespace rows;  // NOLINT(google-build-using-namespace): the shared row helpers

// ---- Dense
// ----------------------------------------------------------------------------------------------------

Dense::Dense(ParamLayout& layout, const std::string& name, int in, int out, Activation act, KernelInit init,
             bool register_product)
    : in_(in), out_(out), act_(act) {
  switch (init.kind) {
    case Init::kNormal:
      w_ = layout.add_kernel_normal(name + "/w", in, out, init.std);
      break;
    case Init::kNormc:
      w_ = layout.add_kernel_normc(name + "/w", in, out, init.std);
      break;
    default:
      w_ = layout.add_kernel_xavier(name + "/w", in, out, static_cast<float>(in), static_cast<float>(out));
      break;
  }
  b_ = layout.add_vector(name + "/b", out, Init::kZeros);
  if (register_product) id_ = layout.add_product({w_, in, out, {}});
}

void Dense::forward_linear(const Weights& params, CMat x, Mat z) const {
  assert(x.cols == in_ && z.cols == out_ && x.rows == z.rows);
  matmul(params, id_, params.values + w_, x, z, false);
}

void Dense::forward(const Weights& params, const SharedRows& x, Mat y) const {
  assert(x.mat.cols == in_ && y.cols == out_ && x.mat.rows == y.rows);
  dense_forward(params, id_, x, params.values + w_, params.values + b_, act_, y);
}

void Dense::backward(const Weights& params, float* grads, const SharedRows& x, CMat y, Mat dy, Mat dx,
                     bool accumulate_dx) const {
  if (act_ == Activation::kRelu)
    for (int r = 0; r < dy.rows; ++r) relu_mask(dy.row(r), y.row(r), out_, dy.row(r));
  backward_preact(params, grads, x, dy, dx, accumulate_dx);
}

void Dense::backward_preact(const Weights& params, float* grads, const SharedRows& x, CMat dz, Mat dx,
                            bool accumulate_dx) const {
  assert(x.mat.cols == in_ && dz.cols == out_ && x.mat.rows == dz.rows);
  matmul_grad(params, x, dz, grads + w_, true);
  add_col_sums(grads + b_, dz);
  if (dx.empty()) return;
  matmul_t(params, id_, params.values + w_, dz, dx, accumulate_dx);
}

// ---- LayerNorm
// ------------------------------------------------------------------------------------------------

LayerNorm::LayerNorm(ParamLayout& layout, const std::string& name, int n) : n_(n) {
  gain_ = layout.add_vector(name + "/gain", n, Init::kOnes);
  bias_ = layout.add_vector(name + "/bias", n, Init::kZeros);
}

namespace {

// A layer norm's forward pass over `rows` rows, kernels::kNormRows at a time (their sums reduced together):
// row r reads in_row(r) and writes out_row(r) and, unless a_row gives null, its activations to a_row(r).
template <class In, class ActRow, class Out>
void norm_forward(const float* gain, const float* bias, int n, const float* pre_bias, Activation act,
                  int rows, In&& in_row, ActRow&& a_row, Out&& out_row, float* stats) {
  const float* in[kernels::kNormRows];
  float* a[kernels::kNormRows];
  float* out[kernels::kNormRows];
  for (int r0 = 0; r0 < rows; r0 += kernels::kNormRows) {
    const int count = std::min(kernels::kNormRows, rows - r0);
    for (int i = 0; i < count; ++i) {
      in[i] = in_row(r0 + i);
      a[i] = a_row(r0 + i);
      out[i] = out_row(r0 + i);
    }
    kernels::act_layer_norm_rows(count, in, pre_bias, act, gain, bias, n, a, out,
                                 stats + 2 * static_cast<ptrdiff_t>(r0));
  }
}

float* no_row(int /*r*/) {
  return nullptr;
}

}  // namespace

void LayerNorm::forward(const Weights& params, CMat x, Mat y, float* stats) const {
  norm_forward(
      params.values + gain_, params.values + bias_, n_, nullptr, Activation::kNone, x.rows,
      [&](int r) { return x.row(r); }, no_row, [&](int r) { return y.row(r); }, stats);
}

void LayerNorm::forward_scatter(const Weights& params, CMat x, const int32_t* y_rows, Mat y,
                                float* stats) const {
  norm_forward(
      params.values + gain_, params.values + bias_, n_, nullptr, Activation::kNone, x.rows,
      [&](int r) { return x.row(r); }, no_row, [&](int r) { return y.row(y_rows[r]); }, stats);
}

void LayerNorm::forward_fused(const Weights& params, CMat z, const float* pre_bias, Activation act, Mat a,
                              Mat y, float* stats) const {
  norm_forward(
      params.values + gain_, params.values + bias_, n_, pre_bias, act, z.rows,
      [&](int r) { return z.row(r); }, [&](int r) { return a.row(r); }, [&](int r) { return y.row(r); },
      stats);
}

void LayerNorm::backward(const Weights& params, float* grads, CMat x, const float* stats, CMat dy,
                         Mat dx) const {
  for (int r = 0; r < x.rows; ++r)
    kernels::act_layer_norm_backward(x.row(r), stats + 2 * static_cast<ptrdiff_t>(r), params.values + gain_,
                                     dy.row(r), Activation::kNone, n_, grads + gain_, grads + bias_,
                                     dx.row(r));
}

void LayerNorm::backward_gather(const Weights& params, float* grads, CMat x, const float* stats,
                                const int32_t* dy_rows, CMat dy, Mat dx) const {
  for (int r = 0; r < x.rows; ++r)
    kernels::act_layer_norm_backward(x.row(r), stats + 2 * static_cast<ptrdiff_t>(r), params.values + gain_,
                                     dy.row(dy_rows[r]), Activation::kNone, n_, grads + gain_, grads + bias_,
                                     dx.row(r));
}

void LayerNorm::backward_fused(const Weights& params, float* grads, CMat a, const float* stats,
                               Activation act, CMat dy, Mat dz, float* pre_bias_grad) const {
  for (int r = 0; r < a.rows; ++r) {
    kernels::act_layer_norm_backward(a.row(r), stats + 2 * static_cast<ptrdiff_t>(r), params.values + gain_,
                                     dy.row(r), act, n_, grads + gain_, grads + bias_, dz.row(r));
    if (pre_bias_grad != nullptr) add_row(pre_bias_grad, dz.row(r), n_);
  }
}

// ---- CircConv1d
// -----------------------------------------------------------------------------------------------

namespace {

// Longest circularly extended input of one row (channels x (padded length + kernel - 1)), and most
// parameters (kernel x channels x filters + filters), the conv keeps on the stack.
constexpr int kConvMaxExtended = 2048;
constexpr int kConvMaxParams = 256;

// Output positions rounded up to whole vectors: the conv computes the padding positions too (from zeros)
// and never stores them, so no position goes through a scalar tail.
int conv_padded_length(int length) {
  return (length + simd::kWidth - 1) / simd::kWidth * simd::kWidth;
}

// xe[c * le + j] = x[((j - pad) mod length) * in_ch + c] for j < length + kernel - 1 and 0 up to
// le = padded length + kernel - 1: the row's channels, each circularly padded, so tap k of output position p
// reads xe[c * le + p + k].
void extend_circular(const float* x, int length, int in_ch, int kernel, float* xe) {
  const int pad = kernel / 2, le = conv_padded_length(length) + kernel - 1;
  for (int c = 0; c < in_ch; ++c) {
    for (int j = 0; j < length + kernel - 1; ++j) {
      int src = j - pad;  // kernel <= length, so one wrap at most
      if (src < 0) {
        src += length;
      } else if (src >= length) {
        src -= length;
      }
      xe[c * le + j] = x[src * in_ch + c];
    }
    for (int j = length + kernel - 1; j < le; ++j) xe[c * le + j] = 0.0f;
  }
}

// The general backward pass's lane sums (CircConv1d::backward's accumulators, lanes [(taps + 1) * out_ch,
// width]: w's, then b's, added to): per row, dy masked by the ReLU in place, then per filter its output
// gradient at every position (zero past the length) against the extended input, a vector of positions at a
// time.
void conv_backward_lanes(int length, int in_ch, int out_ch, int kernel, CMat x, CMat y, Mat dy,
                         float* lanes) {
  using simd::Batch;
  const int lp = conv_padded_length(length), le = lp + kernel - 1;
  const int taps = kernel * in_ch;
  float xe[kConvMaxExtended];
  float dz[kConvMaxExtended];
  for (int p = length; p < lp; ++p) dz[p] = 0.0f;
  for (int r = 0; r < x.rows; ++r) {
    extend_circular(x.row(r), length, in_ch, kernel, xe);
    float* dr = dy.row(r);
    relu_mask(dr, y.row(r), length * out_ch, dr);
    for (int f = 0; f < out_ch; ++f) {
      for (int p = 0; p < length; ++p) dz[p] = dr[p * out_ch + f];
      float* lb = lanes + (taps * out_ch + f) * simd::kWidth;
      for (int p = 0; p < lp; p += simd::kWidth) {
        const Batch d = load<Batch>(dz + p);
        store(lb, load<Batch>(lb) + d);
        for (int k = 0; k < kernel; ++k)
          for (int c = 0; c < in_ch; ++c) {
            float* lw = lanes + ((k * in_ch + c) * out_ch + f) * simd::kWidth;
            store(lw, simd::fma(d, load<Batch>(xe + c * le + p + k), load<Batch>(lw)));
          }
      }
    }
  }
}

#if defined(__AVX512F__)
// The one-channel passes below work in AVX-512's 16-float vectors, which are also simd::kWidth's lanes of the
// general pass's accumulators that they share.
static_assert(simd::kWidth == 16, "AVX-512 builds run 16-float vectors");
constexpr int kConvPermutedMaxKernel = 5;
constexpr int kConvPermutedMaxVecs = 32;  // length <= 32, out_ch <= 16: 512 outputs

using simd::first_lanes;

// A row's circular extension xe[j] = x[(j - kernel / 2) mod length] for j < 32, in two registers (built by
// two permutes of the row's two vectors).
class CircularRow {
 public:
  CircularRow(int length, int kernel) : length_(length) {
    alignas(64) int32_t ext[32];
    for (int j = 0; j < 32; ++j) ext[j] = ((j - kernel / 2) % length + length) % length;
    ext_lo_ = _mm512_load_si512(ext);
    ext_hi_ = _mm512_load_si512(ext + 16);
  }
  void load(const float* x, __m512& lo, __m512& hi) const {
    const __m512 x_lo = _mm512_maskz_loadu_ps(first_lanes(length_), x);
    const __m512 x_hi =
        length_ > 16 ? _mm512_maskz_loadu_ps(first_lanes(length_ - 16), x + 16) : _mm512_setzero_ps();
    lo = _mm512_permutex2var_ps(x_lo, ext_lo_, x_hi);
    hi = _mm512_permutex2var_ps(x_lo, ext_hi_, x_hi);
  }

 private:
  int length_;
  __m512i ext_lo_, ext_hi_;
};

// CircConv1d's forward pass for one input channel, a row's outputs in their own order ([length, out_ch]):
// per vector of 16 outputs, each lane's input xe[p + k] and weight w[k, f] are picked by permutes from two
// registers (the row's circularly extended input, the weights), its bias b[f] from one. Each output is the
// per-filter pass's chain: b[f], fma over k in order, then the ReLU, so the bits are the same.
void conv1_forward_permuted(const float* w, const float* b, const int32_t* lane_pf, int length, int out_ch,
                            int kernel, CMat x, Mat y) {
  const int outs = length * out_ch;
  const int vecs = (outs + 15) / 16;
  const __m512 w_lo = _mm512_maskz_loadu_ps(first_lanes(kernel * out_ch), w);
  const __m512 w_hi = kernel * out_ch > 16 ? _mm512_maskz_loadu_ps(first_lanes(kernel * out_ch - 16), w + 16)
                                           : _mm512_setzero_ps();
  const __m512 bias = _mm512_maskz_loadu_ps(first_lanes(out_ch), b);
  // Per vector: the lanes' weights for each k and their biases; the lanes' positions p.
  __m512 w_lane[kConvPermutedMaxVecs][kConvPermutedMaxKernel];
  __m512 b_lane[kConvPermutedMaxVecs];
  __m512i p_lane[kConvPermutedMaxVecs];
  for (int v = 0; v < vecs; ++v) {
    const __m512i p = _mm512_loadu_si512(lane_pf + v * 32);
    const __m512i f = _mm512_loadu_si512(lane_pf + v * 32 + 16);
    p_lane[v] = p;
    b_lane[v] = _mm512_permutexvar_ps(f, bias);
    for (int k = 0; k < kernel; ++k)
      w_lane[v][k] = _mm512_permutex2var_ps(w_lo, _mm512_add_epi32(f, _mm512_set1_epi32(k * out_ch)), w_hi);
  }
  const CircularRow extend(length, kernel);
  const __mmask16 last = first_lanes(outs - (vecs - 1) * 16);
  for (int r = 0; r < x.rows; ++r) {
    __m512 xe_lo, xe_hi;
    extend.load(x.row(r), xe_lo, xe_hi);
    float* yr = y.row(r);
    for (int v = 0; v < vecs; ++v) {
      __m512 acc = b_lane[v];
      for (int k = 0; k < kernel; ++k) {
        const __m512i at = _mm512_add_epi32(p_lane[v], _mm512_set1_epi32(k));
        acc = _mm512_fmadd_ps(w_lane[v][k], _mm512_permutex2var_ps(xe_lo, at, xe_hi), acc);
      }
      _mm512_mask_storeu_ps(yr + v * 16, v == vecs - 1 ? last : first_lanes(16),
                            _mm512_max_ps(acc, _mm512_setzero_ps()));
    }
  }
}

// conv_backward_lanes for one input channel: the same chains, with the extended input in registers (zero
// lanes where the memory form holds its zero padding) and each filter's output gradient (a column of dy) at
// 16 positions from one transposition: the 16 positions' out_ch gradients (one masked load each, zeros past
// the length) transposed in registers give every filter's vector at once.
void conv1_backward_permuted(int length, int out_ch, int kernel, CMat x, CMat y, Mat dy, float* lanes) {
  const int blocks = conv_padded_length(length) / 16;
  const CircularRow extend(length, kernel);
  const __m512i iota = _mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0);
  const __mmask16 filters = first_lanes(out_ch);
  __m512 acc[(kConvPermutedMaxKernel + 1) * 16];
  const int naccs = (kernel + 1) * out_ch;
  for (int i = 0; i < naccs; ++i) acc[i] = _mm512_load_ps(lanes + i * 16);
  for (int r = 0; r < x.rows; ++r) {
    __m512 xe_lo, xe_hi;
    extend.load(x.row(r), xe_lo, xe_hi);
    // xk[b * kernel + k]: xe[16 b + k + lane], zero from length + kernel - 1 on (the padding).
    __m512 xk[2 * kConvPermutedMaxKernel];
    for (int b = 0; b < blocks; ++b)
      for (int k = 0; k < kernel; ++k)
        xk[b * kernel + k] =
            _mm512_maskz_permutex2var_ps(first_lanes(length + kernel - 1 - 16 * b - k), xe_lo,
                                         _mm512_add_epi32(iota, _mm512_set1_epi32(16 * b + k)), xe_hi);
    float* dr = dy.row(r);
    relu_mask(dr, y.row(r), length * out_ch, dr);
    for (int b = 0; b < blocks; ++b) {
      // d[f] lane l: dy at position 16 b + l, filter f (zero past the length).
      __m512i d[16];
      for (int l = 0; l < 16; ++l)
        d[l] = 16 * b + l < length
                   ? _mm512_maskz_loadu_epi32(filters, dr + static_cast<ptrdiff_t>(16 * b + l) * out_ch)
                   : _mm512_setzero_si512();
      transpose16(d);
      for (int f = 0; f < out_ch; ++f) {
        const __m512 df = _mm512_castsi512_ps(d[f]);
        acc[kernel * out_ch + f] = _mm512_add_ps(acc[kernel * out_ch + f], df);
        for (int k = 0; k < kernel; ++k)
          acc[k * out_ch + f] = _mm512_fmadd_ps(df, xk[b * kernel + k], acc[k * out_ch + f]);
      }
    }
  }
  for (int i = 0; i < naccs; ++i) _mm512_store_ps(lanes + i * 16, acc[i]);
}
#endif

}  // namespace

CircConv1d::CircConv1d(ParamLayout& layout, const std::string& name, int length, int in_ch, int out_ch,
                       int kernel)
    : length_(length), in_ch_(in_ch), out_ch_(out_ch), kernel_(kernel) {
  HNS_NN_CHECK(kernel % 2 == 1, "circular conv kernel must be odd");
  HNS_NN_CHECK(kernel <= length, "circular conv kernel wider than the input");
  HNS_NN_CHECK(in_ch * (conv_padded_length(length) + kernel - 1) <= kConvMaxExtended,
               "circular conv input too long");
  HNS_NN_CHECK((kernel * in_ch + 1) * out_ch <= kConvMaxParams, "circular conv has too many parameters");
  w_ = layout.add_kernel_xavier(name + "/w", kernel * in_ch, out_ch, static_cast<float>(kernel * in_ch),
                                static_cast<float>(kernel * out_ch));
  b_ = layout.add_vector(name + "/b", out_ch, Init::kZeros);
#if defined(__AVX512F__)
  if (in_ch == 1 && length + kernel - 1 <= 32 && kernel <= kConvPermutedMaxKernel && kernel * out_ch <= 32 &&
      out_ch <= 16) {
    const int vecs = (length * out_ch + 15) / 16;
    lane_pf_.assign(static_cast<size_t>(vecs) * 32, 0);  // lanes past the outputs: p = f = 0 (not stored)
    for (int q = 0; q < length * out_ch; ++q) {
      lane_pf_[size_t(q / 16) * 32 + size_t(q % 16)] = q / out_ch;
      lane_pf_[size_t(q / 16) * 32 + 16 + size_t(q % 16)] = q % out_ch;
    }
  }
#endif
}

// acc[p] = b[f] + sum_{k, c} w[k, c, f] xe_c[p + k], then the ReLU: per row and filter, vectorised over
// output positions, or (AVX-512, one channel) in the output's own order, conv1_forward_permuted.
void CircConv1d::forward(const Weights& params, CMat x, Mat y) const {
  const float* w = params.values + w_;
  const float* b = params.values + b_;
#if defined(__AVX512F__)
  if (!lane_pf_.empty())
    return conv1_forward_permuted(w, b, lane_pf_.data(), length_, out_ch_, kernel_, x, y);
#endif
  const int lp = conv_padded_length(length_), le = lp + kernel_ - 1;
  float xe[kConvMaxExtended];
  float acc[kConvMaxExtended];
  for (int r = 0; r < x.rows; ++r) {
    extend_circular(x.row(r), length_, in_ch_, kernel_, xe);
    float* yr = y.row(r);
    for (int f = 0; f < out_ch_; ++f) {
      simd::for_each<true>(lp, [&](auto tag, int p) {
        using F = decltype(tag);
        F v(b[f]);
        for (int k = 0; k < kernel_; ++k)
          for (int c = 0; c < in_ch_; ++c)
            v = simd::fma(F(w[(k * in_ch_ + c) * out_ch_ + f]), load<F>(xe + c * le + p + k), v);
        store(acc + p, simd::max(v, F(0.0f)));
      });
      for (int p = 0; p < length_; ++p) yr[p * out_ch_ + f] = acc[p];
    }
  }
}

// The weight and bias gradients are summed over the rows lane by lane (one vector accumulator per
// parameter), and each reduced once at the end.
void CircConv1d::backward(const Weights& /*params*/, float* grads, CMat x, CMat y, Mat dy) const {
  float* gw = grads + w_;
  float* gb = grads + b_;
  const int taps = kernel_ * in_ch_;
  alignas(64) float lanes[kConvMaxParams * simd::kWidth];  // [(taps + 1) * out_ch, width]: w's, then b's
  std::fill_n(lanes, (taps + 1) * out_ch_ * simd::kWidth, 0.0f);
  bool summed = false;
#if defined(__AVX512F__)
  if (!lane_pf_.empty()) {
    conv1_backward_permuted(length_, out_ch_, kernel_, x, y, dy, lanes);
    summed = true;
  }
#endif
  if (!summed) conv_backward_lanes(length_, in_ch_, out_ch_, kernel_, x, y, dy, lanes);
  for (int i = 0; i < (taps + 1) * out_ch_; ++i) {
    float sum = 0.0f;
    for (int l = 0; l < simd::kWidth; ++l) sum += lanes[i * simd::kWidth + l];
    if (i < taps * out_ch_) {
      gw[i] += sum;
    } else {
      gb[i - taps * out_ch_] += sum;
    }
  }
}

// ---- EntityEmbedding
// ------------------------------------------------------------------------------------------

EntityEmbedding::EntityEmbedding(ParamLayout& layout, const std::string& name, int main_width, int features,
                                 int width)
    : main_width_(main_width), features_(features), width_(width) {
  const int in = main_width + features;
  w_ = layout.add_kernel_xavier(name + "/w", in, width, static_cast<float>(in), static_cast<float>(width));
  b_ = layout.add_vector(name + "/b", width, Init::kZeros);
  main_id_ = layout.add_product({w_, main_width, width, {}});
  ent_id_ = layout.add_product({w_ + static_cast<size_t>(main_width) * width, features, width, {}});
}

void EntityEmbedding::forward(const Weights& params, const SharedRows& main, CMat ent, const EntitySlots& out,
                              Mat scratch) const {
  const float* w_ent = params.values + w_ + static_cast<size_t>(main_width_) * width_;
  // The x_self part once per row, with the bias.
  matmul_bias(params, main_id_, params.values + w_, params.values + b_, main, scratch);
  // The entity part: every slot starts from its row's x_self part (the broadcast), one strided product per
  // entity slot adds to it, then the ReLU.
  for (int r = 0; r < out.rows; ++r)
    for (int e = 0; e < out.count; ++e) std::memcpy(out.at(r, e), scratch.row(r), sizeof(float) * width_);
  for (int e = 0; e < out.count; ++e)
    matmul(params, ent_id_, w_ent, ent.every(e, out.count, out.rows), out.slot(e), true);
  for (int r = 0; r < out.rows; ++r)
    kernels::bias_act(out.at(r, 0), nullptr, Activation::kRelu, out.count * width_);
}

void EntityEmbedding::backward(const Weights& params, float* grads, const SharedRows& main, CMat ent,
                               const EntitySlots& out, const EntitySlots& dout, Mat scratch_rows,
                               Mat scratch_ent, Mat d_main) const {
  // dz[r * count + e] = dout[r, e] masked by ReLU; dsum[r] = sum_e dz[r * count + e].
  for (int r = 0; r < out.rows; ++r) {
    float* sum = scratch_rows.row(r);
    std::memset(sum, 0, sizeof(float) * width_);
    for (int e = 0; e < out.count; ++e) {
      const float* o = out.at(r, e);
      const float* d = dout.at(r, e);
      float* z = scratch_ent.row(r * out.count + e);
      relu_mask(d, o, width_, z);
      add_row(sum, z, width_);
    }
  }
  matmul_grad(params, ent, scratch_ent, grads + w_ + static_cast<size_t>(main_width_) * width_, true);
  matmul_grad(params, main, scratch_rows, grads + w_, true);
  add_col_sums(grads + b_, scratch_rows);
  matmul_t(params, main_id_, params.values + w_, scratch_rows, d_main, true);
}

// ---- Lstm
// -----------------------------------------------------------------------------------------------------

void Lstm::Buffers::bind(Arena& arena) {
  const size_t rows = static_cast<size_t>(sequences) * steps;
  gates = arena.take(rows * 4 * units);
  c = arena.take(rows * units);
  tanh_c = arena.take(rows * units);
  h = arena.take(rows * units);
  c_prev = arena.take(rows * units);
  h_prev = arena.take(rows * units);
  d_gates = arena.take(rows * 4 * units);
  packed.w_h = arena.take(kernels::gemm_packed_floats(units, 4 * units));
  packed.w_h_t = arena.take(kernels::gemm_packed_floats(4 * units, units));
  dh = arena.take(static_cast<size_t>(sequences) * units);
  dc = arena.take(static_cast<size_t>(sequences) * units);
}

Lstm::Lstm(ParamLayout& layout, const std::string& name, int in, int units) : in_(in), units_(units) {
  w_ = layout.add_kernel_xavier(name + "/w", in + units, 4 * units, static_cast<float>(in + units),
                                static_cast<float>(4 * units));
  b_ = layout.add_vector(name + "/b", 4 * units, Init::kZeros);
  wx_id_ = layout.add_product({w_, in, 4 * units, {}});
  wh_id_ = layout.add_product({w_ + static_cast<size_t>(in) * 4 * units, units, 4 * units, {}});
}

void Lstm::pack(const float* params, bool for_backward, Packed& out) const {
  const int u = units_, g4 = 4 * units_;
  const float* w_h = params + w_ + static_cast<size_t>(in_) * g4;
  kernels::gemm_pack(w_h, g4, u, g4, false, out.w_h);
  if (for_backward) kernels::gemm_pack(w_h, g4, g4, u, true, out.w_h_t);
}

void Lstm::forward(const Weights& params, CMat x, int sequences, int steps, const float* reset,
                   const float* state_in, Buffers& bufs, float* state_out, const Packed* packed) const {
  const int u = units_;
  const int g4 = 4 * u;
  const int rows = sequences * steps;
  assert(x.rows == rows && x.cols == in_ && sequences <= bufs.sequences && steps == bufs.steps);
  // The recurrent kernel: packed float W_h (fp32), or the packed bf16 weights.
  const float* w_h_packed = packed != nullptr ? packed->w_h : bufs.packed.w_h;
  if (packed == nullptr && !params.bf16())
    kernels::gemm_pack(params.values + w_ + static_cast<size_t>(in_) * g4, g4, u, g4, false, bufs.packed.w_h);
  // Input contributions of every step at once.
  dense_forward(params, wx_id_, x, params.values + w_, params.values + b_, Activation::kNone,
                Mat(bufs.gates, rows, g4));
  for (int t = 0; t < steps; ++t) {
    // State entering step t: the previous step's, the caller's at t = 0, zero after a reset.
    for (int b = 0; b < sequences; ++b) {
      const int row = b * steps + t;
      float* cp = bufs.c_prev + static_cast<ptrdiff_t>(row) * u;
      float* hp = bufs.h_prev + static_cast<ptrdiff_t>(row) * u;
      if ((reset != nullptr && reset[row] != 0.0f) || (t == 0 && state_in == nullptr)) {
        std::memset(cp, 0, sizeof(float) * u);
        std::memset(hp, 0, sizeof(float) * u);
      } else if (t == 0) {
        std::memcpy(cp, state_in + static_cast<ptrdiff_t>(b) * 2 * u, sizeof(float) * u);
        std::memcpy(hp, state_in + static_cast<ptrdiff_t>(b) * 2 * u + u, sizeof(float) * u);
      } else {
        std::memcpy(cp, bufs.c + static_cast<ptrdiff_t>(row - 1) * u, sizeof(float) * u);
        std::memcpy(hp, bufs.h + static_cast<ptrdiff_t>(row - 1) * u, sizeof(float) * u);
      }
    }
    // Recurrent contribution for step t (rows t, t + steps, ...), then the cell nonlinearities.
    const int ld_h = steps * u, ld_g = steps * g4;
    if (params.bf16()) {
      matmul(params, wh_id_, nullptr, CMat(bufs.h_prev + static_cast<ptrdiff_t>(t) * u, sequences, u, ld_h),
             Mat(bufs.gates + static_cast<ptrdiff_t>(t) * g4, sequences, g4, ld_g), true);
    } else {
      kernels::gemm_acc_packed(bufs.h_prev + static_cast<ptrdiff_t>(t) * u, ld_h, w_h_packed, sequences, u,
                               g4, bufs.gates + static_cast<ptrdiff_t>(t) * g4, ld_g);
    }
    for (int b = 0; b < sequences; ++b) {
      const ptrdiff_t row = b * steps + t;
      float* g = bufs.gates + row * g4;
      kernels::lstm_cell(g, bufs.c_prev + row * u, u, g, bufs.c + row * u, bufs.tanh_c + row * u,
                         bufs.h + row * u);
    }
  }
  if (state_out != nullptr) {
    for (int b = 0; b < sequences; ++b) {
      const ptrdiff_t row = b * steps + steps - 1;
      std::memcpy(state_out + static_cast<ptrdiff_t>(b) * 2 * u, bufs.c + row * u, sizeof(float) * u);
      std::memcpy(state_out + static_cast<ptrdiff_t>(b) * 2 * u + u, bufs.h + row * u, sizeof(float) * u);
    }
  }
}

void Lstm::backward(const Weights& params, float* grads, CMat x, int sequences, int steps, const float* reset,
                    Buffers& bufs, CMat dh, Mat dx, const Packed* packed) const {
  const int u = units_;
  const int g4 = 4 * u;
  const int rows = sequences * steps;
  const float* w_h_t_packed = packed != nullptr ? packed->w_h_t : bufs.packed.w_h_t;
  if (packed == nullptr && steps > 1 && !params.bf16())
    kernels::gemm_pack(params.values + w_ + static_cast<size_t>(in_) * g4, g4, g4, u, true,
                       bufs.packed.w_h_t);
  Mat dh_carry(bufs.dh, sequences, u);
  Mat dc_carry(bufs.dc, sequences, u);
  zero_mat(dh_carry);
  zero_mat(dc_carry);
  Mat d_gates(bufs.d_gates, rows, g4);
  for (int t = steps - 1; t >= 0; --t) {
    for (int b = 0; b < sequences; ++b) {
      const ptrdiff_t row = b * steps + t;
      float* dhb = dh_carry.row(b);
      float* dcb = dc_carry.row(b);
      add_row(dhb, dh.row(static_cast<int>(row)), u);
      kernels::lstm_cell_backward(bufs.gates + row * g4, bufs.c_prev + row * u, bufs.tanh_c + row * u, dhb,
                                  dcb, u, d_gates.row(static_cast<int>(row)), dcb);
    }
    // Gradient w.r.t. the state entering step t; nothing flows past a reset (or out of the chunk).
    if (t == 0) break;
    if (params.bf16()) {
      matmul_t(params, wh_id_, nullptr, CMat(d_gates.row(t), sequences, g4, steps * g4), dh_carry, false);
    } else {
      zero_mat(dh_carry);
      kernels::gemm_acc_packed(d_gates.row(t), static_cast<ptrdiff_t>(steps) * g4, w_h_t_packed, sequences,
                               g4, u, dh_carry.row(0), u);
    }
    for (int b = 0; b < sequences; ++b) {
      if (reset != nullptr && reset[b * steps + t] != 0.0f) {
        std::memset(dh_carry.row(b), 0, sizeof(float) * u);
        std::memset(dc_carry.row(b), 0, sizeof(float) * u);
      }
    }
  }
  matmul_grad2(params, x, grads + w_, CMat(bufs.h_prev, rows, u), grads + w_ + static_cast<size_t>(in_) * g4,
               d_gates, true);
  add_col_sums(grads + b_, d_gates);
  if (!dx.empty()) matmul_t(params, wx_id_, params.values + w_, d_gates, dx, false);
}

}  // namespace hns::nn
