// The entity self-attention layer (residual, optional pre and post layer norms) and masked mean pooling:
// nn/layers.hpp declares them.
#include "nn/layers.hpp"

#include "nn/bf16_gemm.hpp"
#include "nn/row_ops.hpp"
#include "nn/simd.hpp"
#include "nn/transpose16.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace hns::nn {

using namespace rows;  // NOLINT(google-build-using-namespace): the shared row helpers

// ---- SelfAttention
// --------------------------------------------------------------------------------------------

void SelfAttention::Buffers::bind(Arena& arena) {
  // Compact rows are padded to a multiple of kCompactRowAlign.
  const size_t n = static_cast<size_t>(rows) * entities + kCompactRowAlign;
  const size_t dh = width / heads;
  live = arena.take_ints(n);
  offset = arena.take_ints(static_cast<size_t>(rows) + 1);
  ones = arena.take(entities);
  xc = arena.take(n * width);
  xn = arena.take(n * width);
  ln_pre = arena.take(n * 2);
  w_qk = arena.take((static_cast<size_t>(width) + 1) * 2 * width);
  dw_qk = arena.take((static_cast<size_t>(width) + 1) * 2 * width);
  qk = arena.take(n * 2 * width);
  v = arena.take(n * width);
  probs = arena.take(n * heads * entities);
  att = arena.take(n * width);
  res = arena.take(n * width);
  out_c = arena.take(n * width);
  ln_post = arena.take(n * 2);
  d_xn = arena.take(n * width);
  d_qk = arena.take(n * 2 * width);
  d_v = arena.take(n * width);
  d_att = arena.take(n * width);
  d_res = arena.take(n * width);
  d_p = arena.take(static_cast<size_t>(entities) * entities);
  const size_t ld = attention_key_stride(entities);
  kt = arena.take(dh * ld);
  scores = arena.take(static_cast<size_t>(entities) * ld);
  scratch16 =
      reinterpret_cast<bf16::bf16_t*>(arena.take((bf16::attention_scratch_elems(entities, int(dh)) + 1) / 2));
}

SelfAttention::SelfAttention(ParamLayout& layout, const std::string& name, int width, int heads, bool pre_ln,
                             bool post_ln)
    : width_(width), heads_(heads), pre_ln_(pre_ln), post_ln_(post_ln) {
  HNS_NN_CHECK(heads > 0 && width % heads == 0, "attention width must be a multiple of the head count");
  const float std_in = std::sqrt(0.125f / static_cast<float>(width));
  if (pre_ln) ln_pre_ = LayerNorm(layout, name + "/ln_pre", width);
  qk_ = Dense(layout, name + "/qk", width, 2 * width, Activation::kNone, {Init::kNormal, std_in}, false);
  // The q/k product reads Wqk with its columns permuted to [q of every head, k of every head] (permute_qk).
  std::vector<int> qk_order(static_cast<size_t>(2 * width));
  for (int c = 0; c < width; ++c) {
    qk_order[static_cast<size_t>(c)] = 2 * c;
    qk_order[static_cast<size_t>(width + c)] = 2 * c + 1;
  }
  qk_id_ = layout.add_product({qk_.w_offset(), width, 2 * width, std::move(qk_order)});
  v_ = Dense(layout, name + "/v", width, width, Activation::kNone, {Init::kNormal, std_in});
  mlp1_ = Dense(layout, name + "/mlp1", width, width, Activation::kNone, {Init::kNormal, std_in});
  if (post_ln) ln_post_ = LayerNorm(layout, name + "/ln_post", width);
}

double SelfAttention::flops(double entity_rows, double pairs) const {
  // qk, v, mlp1 products plus q k^T and p v.
  return (qk_.flops(1) + v_.flops(1) + mlp1_.flops(1)) * entity_rows + 2.0 * 2.0 * pairs * width_;
}

namespace {

// out[i * ld + j] = sum_c a_i[c] * bt[c * ld + j] for i < count and j < ld (a whole number of vectors; bt's
// columns past the keys are 0), query i at a + i * a_stride: every query of a head against every key at
// once, the keys transposed to [dh, ld]. Each element is one fma chain in c order; the queries go in groups
// of kGroup that share each load of bt, so their chains overlap instead of waiting on one another.
template <int kGroup>
void queries_times_keys_group(const float* a, ptrdiff_t a_stride, int len, const float* bt, int ld,
                              float* out) {
  using simd::Batch;
  for (int j = 0; j < ld; j += simd::kWidth) {
    Batch acc[kGroup];
    for (int q = 0; q < kGroup; ++q) acc[q] = Batch(0.0f);
    for (int c = 0; c < len; ++c) {
      const Batch k = simd::load<Batch>(bt + c * ld + j);
      for (int q = 0; q < kGroup; ++q) acc[q] = simd::fma(Batch(a[q * a_stride + c]), k, acc[q]);
    }
    for (int q = 0; q < kGroup; ++q) simd::store(out + q * ld + j, acc[q]);
  }
}

void queries_times_keys(const float* a, ptrdiff_t a_stride, int count, int len, const float* bt, int ld,
                        float* out) {
  constexpr int kGroup = 4;
  int i = 0;
  for (; i + kGroup <= count; i += kGroup)
    queries_times_keys_group<kGroup>(a + i * a_stride, a_stride, len, bt, ld, out + i * ld);
  switch (count - i) {
    case 3:
      return queries_times_keys_group<3>(a + i * a_stride, a_stride, len, bt, ld, out + i * ld);
    case 2:
      return queries_times_keys_group<2>(a + i * a_stride, a_stride, len, bt, ld, out + i * ld);
    case 1:
      return queries_times_keys_group<1>(a + i * a_stride, a_stride, len, bt, ld, out + i * ld);
    default:
      return;
  }
}

// bt[c * ld + j] = rows[j * row_stride + c] for j < m, c < len. Columns m <= j < ld hold zeros or what they
// held before (an earlier row's keys, or zeros from the pass's start): they only fill the last vector's
// lanes, whose scores nobody reads, and every lane of a vector product is computed apart from the others.
void transpose_keys(const float* rows, ptrdiff_t row_stride, int m, int len, int ld, float* bt) {
#if defined(__AVX512F__)
  // From three keys on, blocks of 16 keys x 16 columns transposed in registers (whole-vector loads and
  // stores, the block's missing keys as zero lanes); fewer keys move element by element below.
  if (simd::kWidth == 16 && m >= 3) {
    for (int j0 = 0; j0 < m; j0 += 16) {
      const int keys = std::min(16, m - j0);
      for (int c0 = 0; c0 < len; c0 += 16) {
        const int cols = std::min(16, len - c0);
        const __mmask16 mask = static_cast<__mmask16>((1u << cols) - 1u);
        __m512i r[16];
        for (int j = 0; j < 16; ++j)
          r[j] = j < keys ? _mm512_maskz_loadu_epi32(mask, rows + (j0 + j) * row_stride + c0)
                          : _mm512_setzero_si512();
        transpose16(r);
        for (int c = 0; c < cols; ++c)
          _mm512_storeu_si512(bt + static_cast<ptrdiff_t>(c0 + c) * ld + j0, r[c]);
      }
    }
    return;
  }
#endif
  // Key by key: the inner loop's trip count is the head width, the same for every row (a loop over a row's
  // few keys inside would end at another count each row, and its branch would miss once per element).
  for (int j = 0; j < m; ++j) {
    const float* src = rows + j * row_stride;
    for (int c = 0; c < len; ++c) bt[static_cast<ptrdiff_t>(c) * ld + j] = src[c];
  }
}

// For each output o < count: out_o[0, len) = init + sum_j w[o * w_out + j * w_stride] * rows[j * row_stride
// + (0, len)] over j < m (out_o at out + o * out_stride; init: its old value when accumulate, else 0). Each
// element is one fma chain in j order (the order of one output at a time); outputs go in groups of
// kGroup, which share every load of `rows`.
template <int kGroup>
void weighted_rows_group(const float* w, ptrdiff_t w_out, ptrdiff_t w_stride, const float* rows,
                         ptrdiff_t row_stride, int m, int len, bool accumulate, float* out,
                         ptrdiff_t out_stride) {
  simd::for_each<true>(len, [&](auto tag, int c) {
    using F = decltype(tag);
    F acc[kGroup];
    for (int o = 0; o < kGroup; ++o) acc[o] = accumulate ? simd::load<F>(out + o * out_stride + c) : F(0.0f);
    for (int j = 0; j < m; ++j) {
      const F x = simd::load<F>(rows + j * row_stride + c);
      for (int o = 0; o < kGroup; ++o) acc[o] = simd::fma(F(w[o * w_out + j * w_stride]), x, acc[o]);
    }
    for (int o = 0; o < kGroup; ++o) simd::store(out + o * out_stride + c, acc[o]);
  });
}

void weighted_rows(const float* w, ptrdiff_t w_out, ptrdiff_t w_stride, int count, const float* rows,
                   ptrdiff_t row_stride, int m, int len, bool accumulate, float* out, ptrdiff_t out_stride) {
  constexpr int kGroup = 4;
  int o = 0;
  for (; o + kGroup <= count; o += kGroup)
    weighted_rows_group<kGroup>(w + o * w_out, w_out, w_stride, rows, row_stride, m, len, accumulate,
                                out + o * out_stride, out_stride);
  for (; o < count; ++o)
    weighted_rows_group<1>(w + o * w_out, w_out, w_stride, rows, row_stride, m, len, accumulate,
                           out + o * out_stride, out_stride);
}

// True where the attention's scores (q k^T forward, da v^T backward) are bf16 products: where the layers'
// products are (bf16 weights) and run on vdpbf16ps, for an even head width. Under the AMX kernels they stay
// float: a head's few keys fill a fraction of a tile, and the one Xeon measured ran vdpbf16ps below its float
// FMA (src/nn/README.md).
bool bf16_scores(const Weights& params, ptrdiff_t dh) {
  return params.bf16() && bf16::kernel() == bf16::Kernel::kAvx512Bf16 && dh % 2 == 0;
}

// Rows [first, last) of x (row stride `stride` floats, contiguous) toward the cache: the next attention row's
// compact rows while this one computes. They were written by a product over the whole chunk and may have
// left the core's caches, and a head reads a narrow slice of each, a pattern the prefetchers follow late.
void prefetch_rows(const float* x, ptrdiff_t stride, int first, int last) {
  const char* begin = reinterpret_cast<const char*>(x + first * stride);
  const char* end = reinterpret_cast<const char*>(x + last * stride);
  for (const char* p = begin; p < end; p += 64) _mm_prefetch(p, _MM_HINT_T0);
}

// Wqk [d, 2d] and bqk [2d] (columns interleaved [heads, dh, (q, k)]) into out [d + 1, 2d]: W's rows, then
// the bias, with column h * dh + i of q at h * dh + i and that of k at d + h * dh + i.
void permute_qk(const float* w, const float* b, int d, float* out) {
  for (int r = 0; r <= d; ++r) {
    const float* src = r < d ? w + static_cast<ptrdiff_t>(r) * 2 * d : b;
    float* dst = out + static_cast<ptrdiff_t>(r) * 2 * d;
    for (int c = 0; c < d; ++c) {
      dst[c] = src[2 * c];
      dst[d + c] = src[2 * c + 1];
    }
  }
}

// The inverse, adding: permuted [d + 1, 2d] gradients into the interleaved dW [d, 2d] and db [2d].
void unpermute_qk_add(const float* g, int d, float* dw, float* db) {
  for (int r = 0; r <= d; ++r) {
    const float* src = g + static_cast<ptrdiff_t>(r) * 2 * d;
    float* dst = r < d ? dw + static_cast<ptrdiff_t>(r) * 2 * d : db;
    for (int c = 0; c < d; ++c) {
      dst[2 * c] += src[c];
      dst[2 * c + 1] += src[d + c];
    }
  }
}

// Zeros to the rows of dst whose entity is masked.
void zero_masked_rows(const float* mask, Mat dst) {
  for (int k = 0; k < dst.rows; ++k)
    if (mask[k] == 0.0f) std::memset(dst.row(k), 0, sizeof(float) * dst.cols);
}

// Row live[i] of dst = a's row i + b's row i (b null: a's row i), for i < n (compact rows to the entities'
// rows), zeros to the rows of masked entities: one pass instead of an add, a copy and a zero fill.
void scatter_compact(CMat a, const float* b, const int32_t* live, int n, const float* mask, Mat dst) {
  const int d = dst.cols;
  for (int i = 0; i < n; ++i) {
    float* out = dst.row(live[i]);
    const float* x = a.row(i);
    if (b == nullptr) {
      std::memcpy(out, x, sizeof(float) * d);
      continue;
    }
    const float* y = b + static_cast<ptrdiff_t>(i) * d;
    simd::for_each<true>(d, [&](auto tag, int c) {
      using F = decltype(tag);
      store(out + c, load<F>(x + c) + load<F>(y + c));
    });
  }
  zero_masked_rows(mask, dst);
}

// Rows [n, n_pad) of m zeroed.
void zero_rows(Mat m, int n, int n_pad) {
  for (int i = n; i < n_pad; ++i) std::memset(m.row(i), 0, sizeof(float) * m.cols);
}

}  // namespace

void SelfAttention::forward(const Weights& params, CMat x, const float* mask, int entities, Buffers& bufs,
                            Mat out) const {
  const int rows = x.rows / entities;
  const int d = width_;
  const ptrdiff_t dh = d / heads_;
  const ptrdiff_t e_count = entities;
  // The unmasked entities of every row, gathered into compact rows.
  int n = 0;
  for (int r = 0; r < rows; ++r) {
    bufs.offset[r] = n;
    for (int e = 0; e < entities; ++e) {
      const int k = r * entities + e;
      if (mask[k] == 0.0f) continue;
      bufs.live[n] = k;
      std::memcpy(bufs.xc + static_cast<ptrdiff_t>(n) * d, x.row(k), sizeof(float) * d);
      ++n;
    }
  }
  bufs.offset[rows] = n;
  bufs.live_count = n;
  const int n_real = n;
  // Padding rows (zeros, results unused) make the products' row count a multiple of kCompactRowAlign.
  n = (n + kCompactRowAlign - 1) / kCompactRowAlign * kCompactRowAlign;
  zero_rows(Mat(bufs.xc, n, d), n_real, n);
  zero_rows(Mat(bufs.att, n, d), n_real, n);
  for (int e = 0; e < entities; ++e) bufs.ones[e] = 1.0f;
  const CMat xc(bufs.xc, n, d);
  CMat xin = xc;
  if (pre_ln_) {
    ln_pre_.forward(params, xc, Mat(bufs.xn, n, d), bufs.ln_pre);
    xin = CMat(bufs.xn, n, d);
  }
  permute_qk(params.values + qk_.w_offset(), params.values + qk_.b_offset(), d, bufs.w_qk);
  // The q/k and v projections multiply the same rows: in bf16 they are converted once for both.
  const SharedRows xs = convert_shared(params, xin);
  dense_forward(params, qk_id_, xs, bufs.w_qk, bufs.w_qk + static_cast<ptrdiff_t>(d) * 2 * d,
                Activation::kNone, Mat(bufs.qk, n, 2 * d));
  v_.forward(params, xs, Mat(bufs.v, n, d));
  const float scale = 1.0f / std::sqrt(static_cast<float>(dh));
  const ptrdiff_t qk_stride = 2 * d;
  const bool bf16_core = bf16_scores(params, dh);
  if (!bf16_core) std::fill_n(bufs.kt, dh * attention_key_stride(entities), 0.0f);  // the float scores' keys
  for (int r = 0; r < rows; ++r) {
    const ptrdiff_t c0 = bufs.offset[r];
    const int m = bufs.offset[r + 1] - bufs.offset[r];
    if (r + 1 < rows) {
      prefetch_rows(bufs.qk, qk_stride, bufs.offset[r + 1], bufs.offset[r + 2]);
      prefetch_rows(bufs.v, d, bufs.offset[r + 1], bufs.offset[r + 2]);
    }
    // Per head: each query against all keys at once (keys transposed), softmax, p·V in registers.
    const int ld = attention_key_stride(m);
    for (int h = 0; h < heads_; ++h) {
      const float* qh = bufs.qk + c0 * qk_stride + h * dh;      // row i: qh + i * qk_stride
      const float* kh = bufs.qk + c0 * qk_stride + d + h * dh;  // row j: kh + j * qk_stride
      float* p = bufs.probs + static_cast<ptrdiff_t>(r * heads_ + h) * e_count * e_count;
      if (bf16_core) {
        bf16::attention_scores(qh, qk_stride, kh, qk_stride, m, static_cast<int>(dh), bufs.scores, ld,
                               bufs.scratch16);
      } else {
        transpose_keys(kh, qk_stride, m, static_cast<int>(dh), ld, bufs.kt);
        queries_times_keys(qh, qk_stride, m, static_cast<int>(dh), bufs.kt, ld, bufs.scores);
      }
      for (int i = 0; i < m; ++i)
        kernels::masked_softmax(bufs.scores + i * ld, bufs.ones, scale, m, p + i * e_count);
      // att_i = sum_j p[i, j] v_j for every query i.
      weighted_rows(p, e_count, 1, m, bufs.v + c0 * d + h * dh, d, m, static_cast<int>(dh), false,
                    bufs.att + c0 * d + h * dh, d);
    }
  }
  // res = x + mlp1(att); out = LN_post(res), compact, then moved to the entities' rows.
  Mat res(bufs.res, n, d);
  mlp1_.forward(params, CMat(bufs.att, n, d), res);
  for (int i = 0; i < n; ++i) add_row(res.row(i), xc.row(i), d);
  // The real rows' norms go straight to their entities' rows; the padding rows' (kept for their stats, which
  // the backward pass reads with a zero gradient) to scratch.
  if (post_ln_) {
    ln_post_.forward_scatter(params, CMat(bufs.res, n_real, d), bufs.live, out, bufs.ln_post);
    ln_post_.forward(params, CMat(res.row(n_real), n - n_real, d), Mat(bufs.out_c, n - n_real, d),
                     bufs.ln_post + 2 * static_cast<ptrdiff_t>(n_real));
    zero_masked_rows(mask, out);
  } else {
    scatter_compact(res, nullptr, bufs.live, n_real, mask, out);
  }
}

void SelfAttention::backward(const Weights& params, float* grads, CMat x, const float* mask, int entities,
                             Buffers& bufs, CMat /*out*/, CMat dout, Mat dx) const {
  const int rows = x.rows / entities;
  const int n_real = bufs.live_count;
  const int n = (n_real + kCompactRowAlign - 1) / kCompactRowAlign * kCompactRowAlign;
  const int d = width_;
  const ptrdiff_t dh = d / heads_;
  const ptrdiff_t e_count = entities;
  const ptrdiff_t qk_stride = 2 * d;
  const float scale = 1.0f / std::sqrt(static_cast<float>(dh));
  // The output gradient of the unmasked entities, compact (a masked entity's output is unused).
  // With the post norm its backward pass reads them from dout's rows (the padding rows' zero gradient after).
  Mat d_res(bufs.d_res, n, d);
  if (post_ln_) {
    ln_post_.backward_gather(params, grads, CMat(bufs.res, n_real, d), bufs.ln_post, bufs.live, dout, d_res);
  } else {
    for (int i = 0; i < n_real; ++i) std::memcpy(d_res.row(i), dout.row(bufs.live[i]), sizeof(float) * d);
  }
  zero_rows(d_res, n_real, n);
  zero_rows(Mat(bufs.d_qk, n, 2 * d), n_real, n);
  if (post_ln_) {
    const Mat d_pad(d_res.row(n_real), n - n_real, d);
    ln_post_.backward(params, grads, CMat(bufs.res + static_cast<ptrdiff_t>(n_real) * d, n - n_real, d),
                      bufs.ln_post + 2 * static_cast<ptrdiff_t>(n_real), d_pad, d_pad);
  }
  mlp1_.backward_preact(params, grads, CMat(bufs.att, n, d), d_res, Mat(bufs.d_att, n, d), false);
  zero_mat(Mat(bufs.d_v, n, d));
  const bool bf16_core = bf16_scores(params, dh);
  if (!bf16_core) std::fill_n(bufs.kt, dh * attention_key_stride(entities), 0.0f);  // the float scores' keys
  for (int r = 0; r < rows; ++r) {
    const ptrdiff_t c0 = bufs.offset[r];
    const int m = bufs.offset[r + 1] - bufs.offset[r];
    if (r + 1 < rows) {
      prefetch_rows(bufs.qk, qk_stride, bufs.offset[r + 1], bufs.offset[r + 2]);
      prefetch_rows(bufs.v, d, bufs.offset[r + 1], bufs.offset[r + 2]);
      prefetch_rows(bufs.d_att, d, bufs.offset[r + 1], bufs.offset[r + 2]);
    }
    for (int h = 0; h < heads_; ++h) {
      const float* qh = bufs.qk + c0 * qk_stride + h * dh;
      const float* kh = bufs.qk + c0 * qk_stride + d + h * dh;
      float* dqh = bufs.d_qk + c0 * qk_stride + h * dh;
      float* dkh = bufs.d_qk + c0 * qk_stride + d + h * dh;
      const float* p = bufs.probs + static_cast<ptrdiff_t>(r * heads_ + h) * e_count * e_count;
      // dp[i, j] = da_i · v_j (values transposed: each da_i against every value at once).
      const int ld = attention_key_stride(m);
      const float* vh = bufs.v + c0 * d + h * dh;
      const float* da = bufs.d_att + c0 * d + h * dh;
      if (bf16_core) {
        bf16::attention_scores(da, d, vh, d, m, static_cast<int>(dh), bufs.scores, ld, bufs.scratch16);
      } else {
        transpose_keys(vh, d, m, static_cast<int>(dh), ld, bufs.kt);
        queries_times_keys(da, d, m, static_cast<int>(dh), bufs.kt, ld, bufs.scores);
      }
      for (int i = 0; i < m; ++i)
        kernels::masked_softmax_backward(p + i * e_count, bufs.scores + i * ld, scale, m,
                                         bufs.d_p + i * e_count);
      // dv_j += sum_i p[i, j] da_i; with dl = d_p (the softmax's input gradient): dq_i = sum_j dl[i, j] k_j,
      // dk_j = sum_i dl[i, j] q_i.
      weighted_rows(p, 1, e_count, m, da, d, m, static_cast<int>(dh), true, bufs.d_v + c0 * d + h * dh, d);
      weighted_rows(bufs.d_p, 1, e_count, m, qh, qk_stride, m, static_cast<int>(dh), false, dkh, qk_stride);
      weighted_rows(bufs.d_p, e_count, 1, m, kh, qk_stride, m, static_cast<int>(dh), false, dqh, qk_stride);
    }
  }
  const CMat xc(bufs.xc, n, d);
  const CMat xin = pre_ln_ ? CMat(bufs.xn, n, d) : xc;
  Mat d_xn(bufs.d_xn, n, d);
  // Wqk's gradient in the permuted order, then added to the interleaved parameter gradient.
  const CMat d_qk(bufs.d_qk, n, 2 * d);
  // The q/k and v weight gradients multiply the same rows: in bf16 their transpose is converted once for
  // both.
  const SharedRows xin_t = convert_shared_t(params, xin);
  matmul_grad(params, xin_t, d_qk, bufs.dw_qk, false);
  float* db_qk = bufs.dw_qk + static_cast<ptrdiff_t>(d) * 2 * d;
  std::memset(db_qk, 0, sizeof(float) * 2 * d);
  add_col_sums(db_qk, d_qk);
  unpermute_qk_add(bufs.dw_qk, d, grads + qk_.w_offset(), grads + qk_.b_offset());
  matmul_t(params, qk_id_, bufs.w_qk, d_qk, d_xn, false);
  v_.backward_preact(params, grads, xin_t, CMat(bufs.d_v, n, d), d_xn, true);
  // dx: compact first (in d_xn; the residual path included), then moved to the entities' rows.
  if (pre_ln_) ln_pre_.backward(params, grads, xc, bufs.ln_pre, d_xn, d_xn);
  scatter_compact(d_xn, bufs.d_res, bufs.live, n_real, mask, dx);
}

// ---- Masked mean pooling
// --------------------------------------------------------------------------------------

void masked_mean_pool(CMat x, const float* mask, int entities, Mat out) {
  for (int r = 0; r < out.rows; ++r) {
    const float* m = mask + static_cast<ptrdiff_t>(r) * entities;
    float msum = 0.0f;
    for (int e = 0; e < entities; ++e) msum += m[e];
    float* o = out.row(r);
    std::memset(o, 0, sizeof(float) * out.cols);
    for (int e = 0; e < entities; ++e)
      if (m[e] != 0.0f) axpy(m[e], x.row(r * entities + e), o, out.cols);
    scale_row(o, 1.0f / (msum + kPoolEps), out.cols);
  }
}

void masked_mean_pool_backward(CMat dout, const float* mask, int entities, Mat dx) {
  for (int r = 0; r < dout.rows; ++r) {
    const float* m = mask + static_cast<ptrdiff_t>(r) * entities;
    float msum = 0.0f;
    for (int e = 0; e < entities; ++e) msum += m[e];
    const float inv = 1.0f / (msum + kPoolEps);
    const float* d = dout.row(r);
    for (int e = 0; e < entities; ++e) {
      float* o = dx.row(r * entities + e);
      const float s = m[e] * inv;
      simd::for_each<true>(dout.cols, [&](auto tag, int i) {
        using F = decltype(tag);
        store(o + i, F(s) * load<F>(d + i));
      });
    }
  }
}

}  // namespace hns::nn
