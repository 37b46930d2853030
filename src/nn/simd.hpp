// One arithmetic for two paths: every function here has a float overload and an xsimd batch overload that
// perform the same IEEE operations lane by lane (fma is fused in both, division is exact in both), so a
// kernel written once as a template gives bit-identical results in its vector loop, its scalar tail and its
// scalar reference. The instruction set is fixed at build time (CMake's HNS_ISA: -mavx2 -mfma,
// -march=x86-64-v4 or -march=native).
#pragma once

#include <xsimd/xsimd.hpp>

#include <immintrin.h>

#include <bit>
#include <cmath>
#include <cstdint>

namespace hns::nn::simd {

using Batch = xsimd::batch<float>;
using IBatch = xsimd::batch<int32_t>;
inline constexpr int kWidth = static_cast<int>(Batch::size);

template <class F>
inline F load(const float* p) {
  if constexpr (std::is_same_v<F, float>) {
    return *p;
  } else {
    return Batch::load_unaligned(p);
  }
}
inline void store(float* p, float v) {
  *p = v;
}
inline void store(float* p, const Batch& v) {
  v.store_unaligned(p);
}

inline float fma(float a, float b, float c) {
  return std::fma(a, b, c);
}
inline Batch fma(const Batch& a, const Batch& b, const Batch& c) {
#if defined(__AVX512F__)
  // xsimd 8 has no AVX-512 fma: its generic fallback multiplies and adds, rounding twice.
  return Batch(_mm512_fmadd_ps(a, b, c));
#else
  return xsimd::fma(a, b, c);
#endif
}
#if defined(__AVX512F__)
// The mask of a vector's first `count` lanes (none for count <= 0, all 16 from 16 on).
inline __mmask16 first_lanes(int count) {
  return count >= 16  ? static_cast<__mmask16>(0xFFFF)
         : count <= 0 ? static_cast<__mmask16>(0)
                      : static_cast<__mmask16>((1u << count) - 1u);
}
#endif
// max/min with the x86 rule (a > b ? a : b; a < b ? a : b), identical in both paths. With AVX and AVX-512 the
// vector forms are one instruction each: vmaxps / vminps return their second operand b unless a > b (a < b)
// holds, which is this rule for every input, NaNs and signed zeros included
// (NnSimd.MaxMinFollowTheScalarRule). Narrower vectors compare and blend.
inline float max(float a, float b) {
  return a > b ? a : b;
}
inline Batch max(const Batch& a, const Batch& b) {
#if defined(__AVX512F__)
  return Batch(_mm512_max_ps(a, b));
#elif defined(__AVX__)
  return Batch(_mm256_max_ps(a, b));
#else
  return xsimd::select(a > b, a, b);
#endif
}
inline float min(float a, float b) {
  return a < b ? a : b;
}
inline Batch min(const Batch& a, const Batch& b) {
#if defined(__AVX512F__)
  return Batch(_mm512_min_ps(a, b));
#elif defined(__AVX__)
  return Batch(_mm256_min_ps(a, b));
#else
  return xsimd::select(a < b, a, b);
#endif
}
inline float select(bool c, float a, float b) {
  return c ? a : b;
}
inline Batch select(const xsimd::batch_bool<float>& c, const Batch& a, const Batch& b) {
  return xsimd::select(c, a, b);
}
inline float abs(float a) {
  return std::fabs(a);
}
inline Batch abs(const Batch& a) {
  return xsimd::abs(a);
}
inline float sqrt(float a) {
  return std::sqrt(a);
}
inline Batch sqrt(const Batch& a) {
  return xsimd::sqrt(a);
}

// 2^n for integral-valued n in [-126, 127].
inline float pow2i(float n) {
  return std::bit_cast<float>((static_cast<int32_t>(n) + 127) << 23);
}
inline Batch pow2i(const Batch& n) {
  return xsimd::bitwise_cast<Batch>((xsimd::to_int(n) + IBatch(127)) << 23);
}
inline float round_even(float x) {
  return std::nearbyint(x);
}
inline Batch round_even(const Batch& x) {
  return xsimd::nearbyint(x);
}

// exp(x), relative error below 2e-7 over [-87, 88]; inputs are clamped to that range, so very negative
// logits give a tiny positive number (callers that need an exact 0 multiply by their mask).
template <class F>
inline F exp(F x) {
  x = min(max(x, F(-87.3f)), F(88.3f));
  const F n = round_even(x * F(1.44269504088896341f));
  F r = fma(n, F(-0.693359375f), x);
  r = fma(n, F(2.12194440e-4f), r);
  F p(1.9875691500e-4f);
  p = fma(p, r, F(1.3981999507e-3f));
  p = fma(p, r, F(8.3334519073e-3f));
  p = fma(p, r, F(4.1665795894e-2f));
  p = fma(p, r, F(1.6666665459e-1f));
  p = fma(p, r, F(5.0000001201e-1f));
  p = fma(p, r * r, r) + F(1.0f);
  return p * pow2i(n);
}

// Logistic sigmoid 1 / (1 + exp(-x)). (Calls inside this namespace are qualified: unqualified ones would find
// xsimd's own exp/tanh for batches by argument-dependent lookup.)
template <class F>
inline F sigmoid(F x) {
  return F(1.0f) / (F(1.0f) + simd::exp(F(0.0f) - x));
}

// tanh(x): odd series for |x| < 0.0625, (1 - e) / (1 + e) with e = exp(-2|x|) above.
template <class F>
inline F tanh(F x) {
  const F ax = abs(x);
  const F e = simd::exp(F(-2.0f) * ax);
  const F big = (F(1.0f) - e) / (F(1.0f) + e);
  const F x2 = x * x;
  F s = fma(x2, F(-17.0f / 315.0f), F(2.0f / 15.0f));
  s = fma(x2, s, F(-1.0f / 3.0f));
  const F small = fma(ax * x2, s, ax);
  const F t = select(ax < F(0.0625f), small, big);
  return select(x < F(0.0f), F(0.0f) - t, t);
}

// Calls body(tag, i) for i in [0, n): tag is a Batch (covering i .. i+kWidth-1) in the vector loop and a
// float in the tail, or always a float when kSimd is false. body loads, computes and stores by itself.
template <bool kSimd, class Body>
inline void for_each(int n, Body&& body) {
  int i = 0;
  if constexpr (kSimd) {
    for (; i + kWidth <= n; i += kWidth) body(Batch(0.0f), i);
  }
  for (; i < n; ++i) body(0.0f, i);
}

// Sums body(tag, i) over i in [0, n) in the vector loop's order: kWidth lane sums over whole batches, added
// in lane order, then the tail in index order. The scalar path (kSimd false) emulates the lanes exactly.
template <bool kSimd, class Body>
inline float sum(int n, Body&& body) {
  int i = 0;
  float lanes[kWidth] = {};
  if constexpr (kSimd) {
    Batch acc(0.0f);
    for (; i + kWidth <= n; i += kWidth) acc = acc + body(Batch(0.0f), i);
    acc.store_unaligned(lanes);
  } else {
    for (; i + kWidth <= n; i += kWidth)
      for (int l = 0; l < kWidth; ++l) lanes[l] = lanes[l] + body(0.0f, i + l);
  }
  float s = 0.0f;
  for (int l = 0; l < kWidth; ++l) s += lanes[l];
  for (; i < n; ++i) s += body(0.0f, i);
  return s;
}

// Maximum of body(tag, i) over i in [0, n) (order does not matter for max); -inf when n == 0.
template <bool kSimd, class Body>
inline float max_of(int n, Body&& body) {
  int i = 0;
  float m = -INFINITY;
  if constexpr (kSimd) {
    if (n >= kWidth) {
      Batch acc(-INFINITY);
      for (; i + kWidth <= n; i += kWidth) acc = max(acc, body(Batch(0.0f), i));
      float lanes[kWidth];
      acc.store_unaligned(lanes);
      for (int l = 0; l < kWidth; ++l) m = max(m, lanes[l]);
    }
  }
  for (; i < n; ++i) m = max(m, body(0.0f, i));
  return m;
}

}  // namespace hns::nn::simd
