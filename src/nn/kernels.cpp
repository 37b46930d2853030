#include "nn/kernels.hpp"

#include <algorithm>
#include <cstring>
#include <string>
#include <type_traits>

#include "nn/isa_features.hpp"
#include "nn/simd.hpp"
#include "nn/tensor.hpp"
#if defined(__AVX512F__)
#include "nn/transpose16.hpp"
#endif

namespace hns::nn::kernels {
namespace {

using simd::Batch;
using simd::load;
using simd::store;

template <class F>
F activate(F x, Activation act) {
  return act == Activation::kRelu ? simd::max(x, F(0.0f)) : x;
}

template <bool kSimd>
void normalize_obs_impl(const float* x, const float* mean, const float* inv_std, const float* row_mask,
                        int rows, int n, float* y) {
  for (int r = 0; r < rows; ++r) {
    const float* xr = x + static_cast<ptrdiff_t>(r) * n;
    float* yr = y + static_cast<ptrdiff_t>(r) * n;
    if (row_mask != nullptr && row_mask[r] == 0.0f) {
      for (int i = 0; i < n; ++i) yr[i] = 0.0f;
      continue;
    }
    simd::for_each<kSimd>(n, [&](auto tag, int i) {
      using F = decltype(tag);
      const F v = (load<F>(xr + i) - load<F>(mean + i)) * load<F>(inv_std + i);
      store(yr + i, simd::min(simd::max(v, F(-kObsClip)), F(kObsClip)));
    });
  }
}

template <bool kSimd>
void bias_act_impl(float* y, const float* bias, Activation act, int n) {
  simd::for_each<kSimd>(n, [&](auto tag, int i) {
    using F = decltype(tag);
    F v = load<F>(y + i);
    if (bias != nullptr) v = v + load<F>(bias + i);
    store(y + i, activate(v, act));
  });
}

template <bool kSimd>
void masked_softmax_impl(const float* logits, const float* mask, float scale, int n, float* p) {
  // l = logits * scale - (1 - mask) * penalty, computed where needed (not stored).
  auto logit = [&](auto tag, int i) {
    using F = decltype(tag);
    return simd::fma(F(1.0f) - load<F>(mask + i), F(-kMaskedLogitPenalty), load<F>(logits + i) * F(scale));
  };
  const float m = simd::max_of<kSimd>(n, logit);
  // e = exp(l - max) * mask, written to p, summed in the vector loop's order.
  const float s = simd::sum<kSimd>(n, [&](auto tag, int i) {
    using F = decltype(tag);
    const F e = simd::exp(logit(tag, i) - F(m)) * load<F>(mask + i);
    store(p + i, e);
    return e;
  });
  const float denom = s + kSoftmaxSumEps;
  simd::for_each<kSimd>(n, [&](auto tag, int i) {
    using F = decltype(tag);
    store(p + i, load<F>(p + i) / F(denom) * load<F>(mask + i));
  });
}

template <bool kSimd>
void masked_softmax_backward_impl(const float* p, const float* dp, float scale, int n, float* dlogits) {
  const float s = simd::sum<kSimd>(n, [&](auto tag, int i) {
    using F = decltype(tag);
    return load<F>(p + i) * load<F>(dp + i);
  });
  simd::for_each<kSimd>(n, [&](auto tag, int i) {
    using F = decltype(tag);
    store(dlogits + i, load<F>(p + i) * (load<F>(dp + i) - F(s)) * F(scale));
  });
}

#if defined(__AVX512F__)
// Rows shorter than a vector (the attention's: one element per key) would run wholly in the scalar tail of
// the two functions above. With AVX-512 they run in one vector instead: masked loads and stores (the lanes
// past n are never read from memory nor written), the same operations per element, and the max and the
// sums over the n real elements in index order, as that tail takes them, so the results equal the scalar
// path's bit for bit. (Only vector stores are read back as scalars: a vector load of scalar stores would
// stall store forwarding.)
constexpr bool kShortRows = simd::kWidth == 16;

using simd::first_lanes;

void masked_softmax_short(const float* logits, const float* mask, float scale, int n, float* p) {
  const __mmask16 k = first_lanes(n);
  alignas(64) float lanes[16];
  const Batch mk(_mm512_maskz_loadu_ps(k, mask));
  const Batch l = simd::fma(Batch(1.0f) - mk, Batch(-kMaskedLogitPenalty),
                            Batch(_mm512_maskz_loadu_ps(k, logits)) * Batch(scale));
  l.store_aligned(lanes);
  float m = -INFINITY;
  for (int i = 0; i < n; ++i) m = simd::max(m, lanes[i]);
  const Batch e = simd::exp(l - Batch(m)) * mk;
  e.store_aligned(lanes);
  float s = 0.0f;
  for (int i = 0; i < n; ++i) s += lanes[i];
  const float denom = s + kSoftmaxSumEps;
  _mm512_mask_storeu_ps(p, k, e / Batch(denom) * mk);
}

void masked_softmax_backward_short(const float* p, const float* dp, float scale, int n, float* dlogits) {
  const __mmask16 k = first_lanes(n);
  alignas(64) float lanes[16];
  const Batch pv(_mm512_maskz_loadu_ps(k, p)), dpv(_mm512_maskz_loadu_ps(k, dp));
  (pv * dpv).store_aligned(lanes);
  float s = 0.0f;
  for (int i = 0; i < n; ++i) s += lanes[i];
  _mm512_mask_storeu_ps(dlogits, k, pv * (dpv - Batch(s)) * Batch(scale));
}
#else
constexpr bool kShortRows = false;
void masked_softmax_short(const float*, const float*, float, int, float*) {}
void masked_softmax_backward_short(const float*, const float*, float, int, float*) {}
#endif

// sums[r] = simd::sum<kSimd>(n, body(r, ...)) for r < count (count <= kNormRows), with the same bits. With
// AVX-512 the rows' vector accumulators are reduced together: one 16 x 16 transposition puts lane l of every
// row in one vector, and adding those vectors in lane order gives each row's sum in the order simd::sum adds
// its lanes, without one serial chain of 16 additions per row. Then each row's tail, in index order.
template <bool kSimd, class Body>
void row_sums(int count, int n, Body&& body, float* sums) {
#if defined(__AVX512F__)
  if constexpr (kSimd && simd::kWidth == 16) {
    if (count > 1) {
      const int full = n / simd::kWidth * simd::kWidth;
      __m512i lanes[16];
      for (int r = 0; r < 16; ++r) {
        Batch acc(0.0f);
        if (r < count)
          for (int i = 0; i < full; i += simd::kWidth) acc = acc + body(r, Batch(0.0f), i);
        lanes[r] = _mm512_castps_si512(acc);
      }
      transpose16(lanes);
      Batch total(0.0f);
      for (int l = 0; l < 16; ++l) total = total + Batch(_mm512_castsi512_ps(lanes[l]));
      alignas(64) float out[16];
      total.store_aligned(out);
      for (int r = 0; r < count; ++r) {
        float t = out[r];
        for (int i = full; i < n; ++i) t += body(r, 0.0f, i);
        sums[r] = t;
      }
      return;
    }
  }
#endif
  for (int r = 0; r < count; ++r)
    sums[r] = simd::sum<kSimd>(n, [&](auto tag, int i) { return body(r, tag, i); });
}

template <bool kSimd>
void act_layer_norm_impl(int count, const float* const* z, const float* pre_bias, Activation act,
                         const float* gain, const float* bias, int n, float* const* a, float* const* y,
                         float* stats) {
  // a = act(z + pre_bias), summed for the mean. Without a bias or activation, a is z itself.
  const bool plain = pre_bias == nullptr && act == Activation::kNone;
  float sums[kNormRows], mean[kNormRows];
  const float* src[kNormRows];
  for (int r = 0; r < count; ++r) src[r] = plain ? z[r] : a[r];
  row_sums<kSimd>(
      count, n,
      [&](int r, auto tag, int i) {
        using F = decltype(tag);
        F v = load<F>(z[r] + i);
        if (plain) return v;
        if (pre_bias != nullptr) v = v + load<F>(pre_bias + i);
        v = activate(v, act);
        store(a[r] + i, v);
        return v;
      },
      sums);
  for (int r = 0; r < count; ++r) mean[r] = n > 0 ? sums[r] / static_cast<float>(n) : 0.0f;
  // Two-pass variance (as tf.nn.moments).
  row_sums<kSimd>(
      count, n,
      [&](int r, auto tag, int i) {
        using F = decltype(tag);
        const F d = load<F>(src[r] + i) - F(mean[r]);
        return d * d;
      },
      sums);
  for (int r = 0; r < count; ++r) {
    const float var = n > 0 ? sums[r] / static_cast<float>(n) : 0.0f;
    const float rstd = 1.0f / std::sqrt(var + kLayerNormEps);
    float* st = stats + 2 * static_cast<ptrdiff_t>(r);
    st[0] = mean[r];
    st[1] = rstd;
    const float* sr = src[r];
    const float m = mean[r];
    float* yr = y[r];
    simd::for_each<kSimd>(n, [&](auto tag, int i) {
      using F = decltype(tag);
      const F xhat = (load<F>(sr + i) - F(m)) * F(rstd);
      store(yr + i, simd::fma(xhat, load<F>(gain + i), load<F>(bias + i)));
    });
  }
}

template <bool kSimd>
void act_layer_norm_backward_impl(const float* a, const float* stats, const float* gain, const float* dy,
                                  Activation act, int n, float* dgain, float* dbias, float* dz) {
  const float mean = stats[0];
  const float rstd = stats[1];
  // g = dy * gain; mean(g) and mean(g * xhat).
  const float sg = simd::sum<kSimd>(n, [&](auto tag, int i) {
    using F = decltype(tag);
    return load<F>(dy + i) * load<F>(gain + i);
  });
  const float sgx = simd::sum<kSimd>(n, [&](auto tag, int i) {
    using F = decltype(tag);
    const F xhat = (load<F>(a + i) - F(mean)) * F(rstd);
    return load<F>(dy + i) * load<F>(gain + i) * xhat;
  });
  const float inv_n = n > 0 ? 1.0f / static_cast<float>(n) : 0.0f;
  const float mg = sg * inv_n;
  const float mgx = sgx * inv_n;
  simd::for_each<kSimd>(n, [&](auto tag, int i) {
    using F = decltype(tag);
    const F av = load<F>(a + i);
    const F d = load<F>(dy + i);
    const F xhat = (av - F(mean)) * F(rstd);
    store(dgain + i, simd::fma(d, xhat, load<F>(dgain + i)));
    store(dbias + i, load<F>(dbias + i) + d);
    F dx = (d * load<F>(gain + i) - F(mg) - xhat * F(mgx)) * F(rstd);
    if (act == Activation::kRelu) dx = simd::select(av > F(0.0f), dx, F(0.0f));
    store(dz + i, dx);
  });
}

// The LSTM cell of units [k, k + width of F): the gates and the new cell state (cell_gates), then tanh(c),
// h and the stores (cell_finish). gate_stride: u, the distance between the gates' blocks in g and gates.
template <class F>
struct CellGates {
  F i, j, f, o, cn;
};
template <class F>
inline CellGates<F> cell_gates(const float* g, const float* c_prev, ptrdiff_t gate_stride, int k) {
  CellGates<F> s;
  s.i = simd::sigmoid(load<F>(g + k));
  s.j = simd::tanh(load<F>(g + gate_stride + k));
  s.f = simd::sigmoid(load<F>(g + 2 * gate_stride + k) + F(kLstmForgetBias));
  s.o = simd::sigmoid(load<F>(g + 3 * gate_stride + k));
  s.cn = simd::fma(load<F>(c_prev + k), s.f, s.i * s.j);
  return s;
}
template <class F>
inline void cell_finish(const CellGates<F>& s, ptrdiff_t gate_stride, int k, float* gates, float* c,
                        float* tanh_c, float* h) {
  const F tc = simd::tanh(s.cn);
  store(gates + k, s.i);
  store(gates + gate_stride + k, s.j);
  store(gates + 2 * gate_stride + k, s.f);
  store(gates + 3 * gate_stride + k, s.o);
  store(c + k, s.cn);
  store(tanh_c + k, tc);
  store(h + k, tc * s.o);
}

template <bool kSimd>
void lstm_cell_impl(const float* g, const float* c_prev, int u, float* gates, float* c, float* tanh_c,
                    float* h) {
  const ptrdiff_t un = u;  // gate block stride
  int k = 0;
  if constexpr (kSimd) {
    // Software-pipelined: a vector's four gates are computed before the previous vector's tanh(c), which
    // depends on that vector's gates through a chain of about 150 cycles; in program order the two chains
    // overlap (1.4x per unit on a Zen 5, with vmaxps/vminps in exp). Every lane's operations are unchanged.
    // Each unit's gates are read before any of its outputs is written, so gates may alias g.
    const int vector_units = u / simd::kWidth * simd::kWidth;
    if (vector_units > 0) {
      CellGates<Batch> cur = cell_gates<Batch>(g, c_prev, un, 0);
      for (; k + simd::kWidth < vector_units; k += simd::kWidth) {
        const CellGates<Batch> next = cell_gates<Batch>(g, c_prev, un, k + simd::kWidth);
        cell_finish(cur, un, k, gates, c, tanh_c, h);
        cur = next;
      }
      cell_finish(cur, un, k, gates, c, tanh_c, h);
      k += simd::kWidth;
    }
  }
  for (; k < u; ++k) cell_finish(cell_gates<float>(g, c_prev, un, k), un, k, gates, c, tanh_c, h);
}

template <bool kSimd>
void lstm_cell_backward_impl(const float* gates, const float* c_prev, const float* tanh_c, const float* dh,
                             const float* dc, int u, float* dg, float* dc_prev) {
  const ptrdiff_t un = u;  // gate block stride
  simd::for_each<kSimd>(u, [&](auto tag, int k) {
    using F = decltype(tag);
    const F one(1.0f);
    const F i = load<F>(gates + k);
    const F j = load<F>(gates + un + k);
    const F f = load<F>(gates + 2 * un + k);
    const F o = load<F>(gates + 3 * un + k);
    const F tc = load<F>(tanh_c + k);
    const F dhk = load<F>(dh + k);
    F dck = dhk * o * (one - tc * tc);
    if (dc != nullptr) dck = dck + load<F>(dc + k);
    store(dg + k, dck * j * i * (one - i));
    store(dg + un + k, dck * i * (one - j * j));
    store(dg + 2 * un + k, dck * load<F>(c_prev + k) * f * (one - f));
    store(dg + 3 * un + k, dhk * tc * o * (one - o));
    store(dc_prev + k, dck * f);
  });
}

// Packed layout of gemm_pack: full panels of kPanel columns, each [k_in, kPanel] contiguous, then the
// n_out % kPanel remaining columns as one narrower panel [k_in, rest]. A register tile is kPanelRows rows x
// one panel: 24 accumulators of AVX-512's 32 registers (12 of AVX2's 16); each loaded vector of b serves
// kPanelRows fmas.
constexpr int kPanelVecs = 4;
constexpr int kPanel = kPanelVecs * simd::kWidth;
constexpr int kPanelRows = simd::kWidth >= 16 ? 6 : 3;

// kRows rows x kVecs vectors (lanes of F each) of y += x b, b read with row stride ldb.
template <class F, int kRows, int kVecs>
inline void gemm_tile(const float* x, ptrdiff_t ldx, const float* b, ptrdiff_t ldb, int k_in, float* y,
                      ptrdiff_t ldy) {
  constexpr int kLanes = std::is_same_v<F, float> ? 1 : simd::kWidth;
  F acc[kRows][kVecs];
  for (int m = 0; m < kRows; ++m)
    for (int v = 0; v < kVecs; ++v) acc[m][v] = load<F>(y + m * ldy + v * kLanes);
  for (int k = 0; k < k_in; ++k) {
    F bk[kVecs];
    for (int v = 0; v < kVecs; ++v) bk[v] = load<F>(b + k * ldb + v * kLanes);
    for (int m = 0; m < kRows; ++m) {
      const F xm(x[m * ldx + k]);
      for (int v = 0; v < kVecs; ++v) acc[m][v] = simd::fma(xm, bk[v], acc[m][v]);
    }
  }
  for (int m = 0; m < kRows; ++m)
    for (int v = 0; v < kVecs; ++v) store(y + m * ldy + v * kLanes, acc[m][v]);
}

// kRows rows of the product across all columns: every full panel, then the narrow one by vectors and
// single columns.
template <bool kSimd, int kRows>
void gemm_panel_rows(const float* x, ptrdiff_t ldx, const float* packed, int k_in, int n_out, float* y,
                     ptrdiff_t ldy) {
  const int full = n_out / kPanel * kPanel;
  for (int n = 0; n < full; n += kPanel) {
    const float* b = packed + static_cast<ptrdiff_t>(n) * k_in;
    if constexpr (kSimd) {
      gemm_tile<Batch, kRows, kPanelVecs>(x, ldx, b, kPanel, k_in, y + n, ldy);
    } else {
      for (int c = 0; c < kPanel; ++c)
        gemm_tile<float, kRows, 1>(x, ldx, b + c, kPanel, k_in, y + n + c, ldy);
    }
  }
  const int rest = n_out - full;
  const float* b = packed + static_cast<ptrdiff_t>(full) * k_in;
  int c = 0;
  if constexpr (kSimd) {
    for (; c + simd::kWidth <= rest; c += simd::kWidth)
      gemm_tile<Batch, kRows, 1>(x, ldx, b + c, rest, k_in, y + full + c, ldy);
  }
  for (; c < rest; ++c) gemm_tile<float, kRows, 1>(x, ldx, b + c, rest, k_in, y + full + c, ldy);
}

// The last rows % kPanelRows rows in one pass (not one pass per row).
template <bool kSimd, int kRows = kPanelRows - 1>
void gemm_tail_rows(int rows, const float* x, ptrdiff_t ldx, const float* packed, int k_in, int n_out,
                    float* y, ptrdiff_t ldy) {
  if constexpr (kRows > 0) {
    if (rows == kRows) return gemm_panel_rows<kSimd, kRows>(x, ldx, packed, k_in, n_out, y, ldy);
    gemm_tail_rows<kSimd, kRows - 1>(rows, x, ldx, packed, k_in, n_out, y, ldy);
  }
}

template <bool kSimd>
void gemm_acc_packed_impl(const float* x, ptrdiff_t ldx, const float* packed, int rows, int k_in, int n_out,
                          float* y, ptrdiff_t ldy) {
  int m = 0;
  for (; m + kPanelRows <= rows; m += kPanelRows)
    gemm_panel_rows<kSimd, kPanelRows>(x + m * ldx, ldx, packed, k_in, n_out, y + m * ldy, ldy);
  gemm_tail_rows<kSimd>(rows - m, x + m * ldx, ldx, packed, k_in, n_out, y + m * ldy, ldy);
}

}  // namespace

size_t gemm_packed_floats(int k_in, int n_out) {
  return static_cast<size_t>(k_in) * n_out;
}

void gemm_pack(const float* w, ptrdiff_t ldw, int k_in, int n_out, bool transpose, float* packed) {
  const int full = n_out / kPanel * kPanel;
  for (int n0 = 0; n0 < n_out; n0 += kPanel) {
    const int width = n0 < full ? kPanel : n_out - full;
    float* panel = packed + static_cast<ptrdiff_t>(n0) * k_in;
    if (transpose) {
      // b[k, n0 + n] = w[n0 + n, k]: blocks of 16 k so that the panel's lines stay in cache.
      for (int k0 = 0; k0 < k_in; k0 += 16)
        for (int n = 0; n < width; ++n)
          for (int k = k0; k < std::min(k_in, k0 + 16); ++k)
            panel[static_cast<ptrdiff_t>(k) * width + n] = w[(n0 + n) * ldw + k];
    } else {
      for (int k = 0; k < k_in; ++k)
        std::memcpy(panel + static_cast<ptrdiff_t>(k) * width, w + k * ldw + n0, sizeof(float) * width);
    }
  }
}

void gemm_acc_packed(const float* x, ptrdiff_t ldx, const float* packed, int rows, int k_in, int n_out,
                     float* y, ptrdiff_t ldy) {
  gemm_acc_packed_impl<true>(x, ldx, packed, rows, k_in, n_out, y, ldy);
}
void gemm_acc_packed_scalar(const float* x, ptrdiff_t ldx, const float* packed, int rows, int k_in, int n_out,
                            float* y, ptrdiff_t ldy) {
  gemm_acc_packed_impl<false>(x, ldx, packed, rows, k_in, n_out, y, ldy);
}

int simd_width() {
  return simd::kWidth;
}

#ifndef HNS_ISA_SETTING
#define HNS_ISA_SETTING "unknown"
#endif

std::string isa_description() {
#if defined(__AVX512F__)
  const char* vector = "AVX-512";
#elif defined(__AVX2__)
  const char* vector = "AVX2";
#else
  const char* vector = "SSE";
#endif
#if defined(__FMA__)
  const char* fma = ", FMA";
#else
  const char* fma = ", no FMA";
#endif
  return std::string(HNS_ISA_SETTING) + " (" + vector + ", " + std::to_string(simd::kWidth) +
         " floats per vector" + fma + ")";
}

// The build's extensions, from the compiler's feature macros (isa_features.hpp).
extern const unsigned kIsaCompiled = 0u
#if defined(__AVX2__)
                                     | kIsaAvx2
#endif
#if defined(__FMA__)
                                     | kIsaFma
#endif
#if defined(__BMI__)
                                     | kIsaBmi
#endif
#if defined(__BMI2__)
                                     | kIsaBmi2
#endif
#if defined(__F16C__)
                                     | kIsaF16c
#endif
#if defined(__AVX512F__)
                                     | kIsaAvx512f
#endif
#if defined(__AVX512BW__)
                                     | kIsaAvx512bw
#endif
#if defined(__AVX512CD__)
                                     | kIsaAvx512cd
#endif
#if defined(__AVX512DQ__)
                                     | kIsaAvx512dq
#endif
#if defined(__AVX512VL__)
                                     | kIsaAvx512vl
#endif
#if defined(__AVX512VNNI__)
                                     | kIsaAvx512vnni
#endif
#if defined(__AVX512BF16__)
                                     | kIsaAvx512bf16
#endif
#if defined(__AVX512IFMA__)
                                     | kIsaAvx512ifma
#endif
#if defined(__AVX512VBMI__)
                                     | kIsaAvx512vbmi
#endif
#if defined(__AVX512VBMI2__)
                                     | kIsaAvx512vbmi2
#endif
#if defined(__AVX512BITALG__)
                                     | kIsaAvx512bitalg
#endif
#if defined(__AVX512VPOPCNTDQ__)
                                     | kIsaAvx512vpopcntdq
#endif
#if defined(__GFNI__)
                                     | kIsaGfni
#endif
#if defined(__VAES__)
                                     | kIsaVaes
#endif
#if defined(__VPCLMULQDQ__)
                                     | kIsaVpclmulqdq
#endif
#if defined(__AVX512VP2INTERSECT__)
                                     | kIsaAvx512vp2intersect
#endif
    ;

std::string isa_unsupported() {
  const char* missing = isa_first_missing();
  if (missing == nullptr) return {};
  return std::string("this build uses ") + missing + " (HNS_ISA=" + HNS_ISA_SETTING +
         "), which this CPU does not have: rebuild with HNS_ISA=avx2 tools/run (or cmake -DHNS_ISA=avx2)";
}

void normalize_obs(const float* x, const float* mean, const float* inv_std, const float* row_mask, int rows,
                   int n, float* y) {
  normalize_obs_impl<true>(x, mean, inv_std, row_mask, rows, n, y);
}
void normalize_obs_scalar(const float* x, const float* mean, const float* inv_std, const float* row_mask,
                          int rows, int n, float* y) {
  normalize_obs_impl<false>(x, mean, inv_std, row_mask, rows, n, y);
}

void bias_act(float* y, const float* bias, Activation act, int n) {
  bias_act_impl<true>(y, bias, act, n);
}
void bias_act_scalar(float* y, const float* bias, Activation act, int n) {
  bias_act_impl<false>(y, bias, act, n);
}

void masked_softmax(const float* logits, const float* mask, float scale, int n, float* p) {
  if (kShortRows && n < simd::kWidth) return masked_softmax_short(logits, mask, scale, n, p);
  masked_softmax_impl<true>(logits, mask, scale, n, p);
}
void masked_softmax_scalar(const float* logits, const float* mask, float scale, int n, float* p) {
  masked_softmax_impl<false>(logits, mask, scale, n, p);
}
void masked_softmax_backward(const float* p, const float* dp, float scale, int n, float* dlogits) {
  if (kShortRows && n < simd::kWidth) return masked_softmax_backward_short(p, dp, scale, n, dlogits);
  masked_softmax_backward_impl<true>(p, dp, scale, n, dlogits);
}
void masked_softmax_backward_scalar(const float* p, const float* dp, float scale, int n, float* dlogits) {
  masked_softmax_backward_impl<false>(p, dp, scale, n, dlogits);
}

void act_layer_norm(const float* z, const float* pre_bias, Activation act, const float* gain,
                    const float* bias, int n, float* a, float* y, float* stats) {
  act_layer_norm_impl<true>(1, &z, pre_bias, act, gain, bias, n, &a, &y, stats);
}
void act_layer_norm_scalar(const float* z, const float* pre_bias, Activation act, const float* gain,
                           const float* bias, int n, float* a, float* y, float* stats) {
  act_layer_norm_impl<false>(1, &z, pre_bias, act, gain, bias, n, &a, &y, stats);
}
void act_layer_norm_rows(int count, const float* const* z, const float* pre_bias, Activation act,
                         const float* gain, const float* bias, int n, float* const* a, float* const* y,
                         float* stats) {
  HNS_NN_CHECK(count >= 0 && count <= kNormRows, "act_layer_norm_rows: more than kNormRows rows");
  act_layer_norm_impl<true>(count, z, pre_bias, act, gain, bias, n, a, y, stats);
}
void act_layer_norm_backward(const float* a, const float* stats, const float* gain, const float* dy,
                             Activation act, int n, float* dgain, float* dbias, float* dz) {
  act_layer_norm_backward_impl<true>(a, stats, gain, dy, act, n, dgain, dbias, dz);
}
void act_layer_norm_backward_scalar(const float* a, const float* stats, const float* gain, const float* dy,
                                    Activation act, int n, float* dgain, float* dbias, float* dz) {
  act_layer_norm_backward_impl<false>(a, stats, gain, dy, act, n, dgain, dbias, dz);
}

void lstm_cell(const float* g, const float* c_prev, int u, float* gates, float* c, float* tanh_c, float* h) {
  lstm_cell_impl<true>(g, c_prev, u, gates, c, tanh_c, h);
}
void lstm_cell_scalar(const float* g, const float* c_prev, int u, float* gates, float* c, float* tanh_c,
                      float* h) {
  lstm_cell_impl<false>(g, c_prev, u, gates, c, tanh_c, h);
}
void lstm_cell_backward(const float* gates, const float* c_prev, const float* tanh_c, const float* dh,
                        const float* dc, int u, float* dg, float* dc_prev) {
  lstm_cell_backward_impl<true>(gates, c_prev, tanh_c, dh, dc, u, dg, dc_prev);
}
void lstm_cell_backward_scalar(const float* gates, const float* c_prev, const float* tanh_c, const float* dh,
                               const float* dc, int u, float* dg, float* dc_prev) {
  lstm_cell_backward_impl<false>(gates, c_prev, tanh_c, dh, dc, u, dg, dc_prev);
}

}  // namespace hns::nn::kernels
