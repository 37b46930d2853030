// A 16 x 16 transposition of 32-bit elements in AVX-512 registers, for the bf16 packing (nn/bf16_gemm.cpp,
// inside functions that carry the bf16 extension as a target attribute), and in AVX-512 builds for the
// attention's key transposition (nn/attention.cpp), the layer norm's row sums (nn/kernels.cpp) and the lidar
// conv's output gradients (nn/layers.cpp). Its own target attribute lets every caller inline it, whatever the
// library's build flags; call it only where the CPU has AVX-512F.
#pragma once

#include <immintrin.h>

#define HNS_TRANSPOSE16_INLINE __attribute__((target("avx512f"))) inline __attribute__((always_inline))

namespace hns::nn {

// 16 x 16 dwords transposed in registers: r[i]'s element j becomes r[j]'s element i.
HNS_TRANSPOSE16_INLINE void transpose16(__m512i r[16]) {
  __m512i t[16];
  for (int i = 0; i < 8; ++i) {
    t[2 * i] = _mm512_unpacklo_epi32(r[2 * i], r[2 * i + 1]);
    t[2 * i + 1] = _mm512_unpackhi_epi32(r[2 * i], r[2 * i + 1]);
  }
  // Within each 128-bit lane L, r[4i + j] then holds element 4L + j of rows 4i .. 4i + 3.
  for (int i = 0; i < 4; ++i) {
    r[4 * i] = _mm512_unpacklo_epi64(t[4 * i], t[4 * i + 2]);
    r[4 * i + 1] = _mm512_unpackhi_epi64(t[4 * i], t[4 * i + 2]);
    r[4 * i + 2] = _mm512_unpacklo_epi64(t[4 * i + 1], t[4 * i + 3]);
    r[4 * i + 3] = _mm512_unpackhi_epi64(t[4 * i + 1], t[4 * i + 3]);
  }
  // Row 4L + j of the result is lane L of r[j], r[4 + j], r[8 + j], r[12 + j].
  for (int j = 0; j < 4; ++j) {
    const __m512i x0 = _mm512_shuffle_i32x4(r[j], r[4 + j], 0x88);  // lanes 0, 2 of each
    const __m512i x1 = _mm512_shuffle_i32x4(r[j], r[4 + j], 0xDD);  // lanes 1, 3
    const __m512i y0 = _mm512_shuffle_i32x4(r[8 + j], r[12 + j], 0x88);
    const __m512i y1 = _mm512_shuffle_i32x4(r[8 + j], r[12 + j], 0xDD);
    t[j] = _mm512_shuffle_i32x4(x0, y0, 0x88);
    t[8 + j] = _mm512_shuffle_i32x4(x0, y0, 0xDD);
    t[4 + j] = _mm512_shuffle_i32x4(x1, y1, 0x88);
    t[12 + j] = _mm512_shuffle_i32x4(x1, y1, 0xDD);
  }
  for (int i = 0; i < 16; ++i) r[i] = t[i];
}

}  // namespace hns::nn
