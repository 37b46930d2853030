// The AVX512-BF16 kernels of nn/bf16_gemm.hpp, the layouts of both kernels and the choice between them (the
// AMX kernel is nn/bf16_amx.cpp). Every function that uses the extension carries it in a target attribute
// (HNS_BF16_TARGET), so this file builds with the library's flags (AVX2 or AVX-512 without BF16) and the
// rest of the library never meets an instruction its CPU may lack; callers check available() first.
#include "nn/bf16_gemm.hpp"

#include <immintrin.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "nn/bf16_amx.hpp"
#include "nn/transpose16.hpp"

#define HNS_BF16_TARGET __attribute__((target("avx512f,avx512bw,avx512vl,avx512dq,avx512bf16")))
#define HNS_BF16_INLINE HNS_BF16_TARGET inline __attribute__((always_inline))

namespace hns::nn::bf16 {
namespace {

constexpr int kRowsPerTile = 6;       // 6 x 4 accumulators of AVX-512's 32 registers
constexpr int kMaxGatherCols = 4096;  // columns of a permuted pack_b

std::atomic<int> g_kernel{-1};  // the Kernel in use; -1 until kernel() first decides

bool tiles(Kernel k) {
  return k != Kernel::kAvx512Bf16;
}
int pairs(int k) {
  return (k + 1) / 2;
}
int round_up(int x, int to) {
  return (x + to - 1) / to * to;
}
// k's pairs padded to the kernel's pair block (B's pairs per panel, half of A's row).
int padded_pairs(int k, Kernel kern) {
  return tiles(kern) ? round_up(pairs(k), amx::kTilePairs) : pairs(k);
}
int padded_rows(int rows, Kernel kern) {
  return tiles(kern) ? round_up(rows, amx::kTileRows) : rows;
}
// Rows of convert_a_transposed's vdpbf16ps layout: a whole number of vectors.
ptrdiff_t transposed_rows(int rows) {
  return (rows + kVecCols - 1) / kVecCols * kVecCols;
}

// The order of C's tiles. Panels outer (each panel of B stays in L1 while the row tiles pass over it) unless
// the product accumulates into a C over 512 KB with a B of at most that: a gradient buffer that arrives
// cold from memory and is read at each tile's start, where nothing overlaps the misses (the LSTM's weight
// gradients of `paper`: C 1 MB, k only a chunk's 160 rows). 512 KB is half the L2 of Zen 4/5 (1 MB per core):
// where C is larger it is unlikely to be cached, and a B that size stays in L2 while every row tile sweeps
// it. Row tiles outer read each of C's rows along its length, which the hardware prefetcher streams, and take
// B from L2. On a Zen 5, C cold: 256 x 160 x 1024 from about 270 to 370 GFLOP/s, 160 x 256 x 1024 from 310 to
// 390 (medians of 6 interleaved runs).
constexpr size_t kColdBytes = size_t(512) << 10;
bool rows_outer(bool accumulate, int rows, int k2, int n) {
  const size_t c_bytes = size_t(rows) * size_t(n) * sizeof(float);
  const size_t b_bytes = size_t(k2) * size_t(n) * 2 * sizeof(bf16_t);
  return accumulate && c_bytes > kColdBytes && b_bytes <= kColdBytes;
}

// ---- vector conversion (float -> bf16, round to nearest even, as from_float)

// 32 floats (lo: elements 0-15, hi: 16-31) to 32 bf16 in order.
HNS_BF16_INLINE __m512i cvt32(__m512 lo, __m512 hi) {
  return reinterpret_cast<__m512i>(_mm512_cvtne2ps_pbh(hi, lo));
}
// Pairs (x0[j], x1[j]) for j < 16: 16 dwords, low half x0's bf16, high half x1's.
HNS_BF16_INLINE __m512i cvt_pairs(__m512 x0, __m512 x1) {
  const __m512i both = cvt32(x0, x1);  // [x0's 16 | x1's 16]
  const __m512i idx = _mm512_set_epi16(31, 15, 30, 14, 29, 13, 28, 12, 27, 11, 26, 10, 25, 9, 24, 8, 23, 7,
                                       22, 6, 21, 5, 20, 4, 19, 3, 18, 2, 17, 1, 16, 0);
  return _mm512_permutexvar_epi16(idx, both);
}
HNS_BF16_INLINE __m512 load_masked(const float* p, int count) {
  if (count >= 16) return _mm512_loadu_ps(p);
  if (count <= 0) return _mm512_setzero_ps();
  return _mm512_maskz_loadu_ps(static_cast<__mmask16>((1u << count) - 1u), p);
}

// The first min(count, 32) of the floats at p as 32 bf16 in order (16 pairs), zeros past count.
HNS_BF16_INLINE __m512i cvt32_masked(const float* p, int count) {
  return cvt32(load_masked(p, count), load_masked(p + 16, count - 16));
}

// ---- the product

// One pair of bf16 read as a 32-bit integer (the broadcast operand of vdpbf16ps); may alias bf16 storage.
using Dword = int32_t __attribute__((may_alias));

// Where A's pair p of row m lies, in dwords from A's start: m * row + p * pair (row layout: row = pairs,
// pair = 1; the transposed layout of convert_a_transposed: row = 1, pair = its row count rounded up).
struct ALayout {
  ptrdiff_t row;
  ptrdiff_t pair;
};

// kRows rows x kVecs vectors of C from A's rows and one panel of B (ldb: the panel's width in columns).
template <int kRows, int kVecs>
HNS_BF16_INLINE void tile(const bf16_t* a, ALayout lda, const bf16_t* b, int ldb, int k2, float* c,
                          ptrdiff_t ldc, bool accumulate, const float* bias, __mmask16 last_mask,
                          const float* next_c) {
  if (accumulate && next_c != nullptr) {
    // The next tile's C into L1 while this one computes. The addresses are integers (a smaller next tile
    // leaves some of them past C's end, where a pointer may not go; a prefetch never faults).
    const uintptr_t next = reinterpret_cast<uintptr_t>(next_c);
    for (int m = 0; m < kRowsPerTile; ++m)
      for (int v = 0; v < 4; ++v)
        _mm_prefetch(reinterpret_cast<const char*>(next + sizeof(float) * size_t(m * ldc + v * kVecCols)),
                     _MM_HINT_T0);
  }
  __m512 acc[kRows][kVecs];
  for (int m = 0; m < kRows; ++m)
    for (int v = 0; v < kVecs; ++v) {
      const __mmask16 mk = v == kVecs - 1 ? last_mask : static_cast<__mmask16>(0xFFFF);
      // The sums start from C (accumulate), from the bias (the same for every row), or from zero.
      acc[m][v] = accumulate        ? _mm512_maskz_loadu_ps(mk, c + m * ldc + v * kVecCols)
                  : bias != nullptr ? _mm512_maskz_loadu_ps(mk, bias + v * kVecCols)
                                    : _mm512_setzero_ps();
    }
  const Dword* a32 = reinterpret_cast<const Dword*>(a);
  for (int p = 0; p < k2; ++p) {
    __m512bh bv[kVecs];
    for (int v = 0; v < kVecs; ++v)
      bv[v] = reinterpret_cast<__m512bh>(
          _mm512_loadu_si512(b + (static_cast<ptrdiff_t>(p) * ldb + v * kVecCols) * 2));
    for (int m = 0; m < kRows; ++m) {
      const __m512bh av = reinterpret_cast<__m512bh>(_mm512_set1_epi32(a32[m * lda.row + p * lda.pair]));
      for (int v = 0; v < kVecs; ++v) acc[m][v] = _mm512_dpbf16_ps(acc[m][v], av, bv[v]);
    }
  }
  for (int m = 0; m < kRows; ++m)
    for (int v = 0; v < kVecs; ++v) {
      const __mmask16 mk = v == kVecs - 1 ? last_mask : static_cast<__mmask16>(0xFFFF);
      _mm512_mask_storeu_ps(c + m * ldc + v * kVecCols, mk, acc[m][v]);
    }
}

template <int kRows>
HNS_BF16_INLINE void tile_cols(int vecs, const bf16_t* a, ALayout lda, const bf16_t* b, int k2, float* c,
                               ptrdiff_t ldc, bool accumulate, const float* bias, __mmask16 last_mask,
                               const float* next_c) {
  const int ldb = vecs * kVecCols;
  switch (vecs) {
    case 4:
      return tile<kRows, 4>(a, lda, b, ldb, k2, c, ldc, accumulate, bias, last_mask, next_c);
    case 3:
      return tile<kRows, 3>(a, lda, b, ldb, k2, c, ldc, accumulate, bias, last_mask, next_c);
    case 2:
      return tile<kRows, 2>(a, lda, b, ldb, k2, c, ldc, accumulate, bias, last_mask, next_c);
    default:
      return tile<kRows, 1>(a, lda, b, ldb, k2, c, ldc, accumulate, bias, last_mask, next_c);
  }
}

// The last rows % kRowsPerTile rows in one pass of tiles of that height.
template <int kRows = kRowsPerTile - 1>
HNS_BF16_INLINE void tail_rows(int rows, int vecs, const bf16_t* a, ALayout lda, const bf16_t* b, int k2,
                               float* c, ptrdiff_t ldc, bool accumulate, const float* bias,
                               __mmask16 last_mask, const float* next_c) {
  if constexpr (kRows > 0) {
    if (rows == kRows)
      return tile_cols<kRows>(vecs, a, lda, b, k2, c, ldc, accumulate, bias, last_mask, next_c);
    tail_rows<kRows - 1>(rows, vecs, a, lda, b, k2, c, ldc, accumulate, bias, last_mask, next_c);
  }
}

// Rows [m, m + h) (h <= kRowsPerTile) of C's columns in the panel starting at n0, summing pairs [0, k2) of
// B's panels of kp pairs each; bias: C's starting row where the sums do not accumulate (null: zeros);
// next_c: where the tile after this one starts in C (null: none).
HNS_BF16_INLINE void panel_rows(const bf16_t* a, ALayout lda, int m, int h, const bf16_t* b, int k2, int kp,
                                int n, int n0, float* c, ptrdiff_t ldc, bool accumulate, const float* bias,
                                const float* next_c) {
  const int width = panel_width(n, n0);
  const int vecs = width / kVecCols;
  const int last_cols = n - n0 - (vecs - 1) * kVecCols;  // columns of the panel's last vector
  const __mmask16 last_mask =
      last_cols >= 16 ? static_cast<__mmask16>(0xFFFF) : static_cast<__mmask16>((1u << last_cols) - 1u);
  const bf16_t* panel = b + static_cast<ptrdiff_t>(n0) * 2 * kp;
  const bf16_t* am = a + m * 2 * lda.row;
  float* cm = c + m * ldc + n0;
  const float* bn = bias == nullptr ? nullptr : bias + n0;
  if (h == kRowsPerTile)
    return tile_cols<kRowsPerTile>(vecs, am, lda, panel, k2, cm, ldc, accumulate, bn, last_mask, next_c);
  tail_rows(h, vecs, am, lda, panel, k2, cm, ldc, accumulate, bn, last_mask, next_c);
}

// C (+)= A B over k2 pairs, B's panels kp >= k2 pairs long (kp = k2 but for gemm_at_pairs).
HNS_BF16_TARGET void gemm_avx512(const bf16_t* a, ALayout lda, int rows, int k2, int kp, const bf16_t* b,
                                 int n, float* c, ptrdiff_t ldc, bool accumulate,
                                 const float* bias = nullptr) {
  // Every element's sum is the same in either order of the tiles below; only the speed differs.
  // Where the tile at (m, n0) starts; null past the last one.
  auto at = [&](int m, int n0) -> const float* { return m < rows && n0 < n ? c + m * ldc + n0 : nullptr; };
  if (rows_outer(accumulate, rows, k2, n)) {
    for (int m = 0; m < rows; m += kRowsPerTile)
      for (int n0 = 0; n0 < n; n0 += kPanel) {
        const float* next = n0 + kPanel < n ? at(m, n0 + kPanel) : at(m + kRowsPerTile, 0);
        panel_rows(a, lda, m, std::min(kRowsPerTile, rows - m), b, k2, kp, n, n0, c, ldc, accumulate, bias,
                   next);
      }
    return;
  }
  for (int n0 = 0; n0 < n; n0 += kPanel)
    for (int m = 0; m < rows; m += kRowsPerTile) {
      const float* next = m + kRowsPerTile < rows ? at(m + kRowsPerTile, n0) : at(0, n0 + kPanel);
      panel_rows(a, lda, m, std::min(kRowsPerTile, rows - m), b, k2, kp, n, n0, c, ldc, accumulate, bias,
                 next);
    }
}

// ---- the attention's scores (vdpbf16ps only)

// Pair p of every key of a block of 16: a row of the block transposed in memory (16 dwords per pair), or a
// register of the block transposed in registers.
HNS_BF16_INLINE __m512bh key_pairs(const bf16_t* kt, int p) {
  return reinterpret_cast<__m512bh>(_mm512_loadu_si512(kt + 2 * static_cast<ptrdiff_t>(p) * 16));
}
HNS_BF16_INLINE __m512bh key_pairs(const __m512i (&kt)[16], int p) {
  return reinterpret_cast<__m512bh>(kt[p]);
}

// One pair of kGroup queries (qp: the first query's pair, the next q_dwords after it) into their chains.
template <int kGroup>
HNS_BF16_INLINE void score_step(const Dword* qp, ptrdiff_t q_dwords, __m512bh keys, __m512 (&acc)[kGroup]) {
  for (int g = 0; g < kGroup; ++g)
    acc[g] = _mm512_dpbf16_ps(acc[g], reinterpret_cast<__m512bh>(_mm512_set1_epi32(qp[g * q_dwords])), keys);
}

// kGroup queries (bf16 pairs: the first query's at qb, each next one q_dwords after the one before) against
// one block of 16 keys (kt, as key_pairs reads it), each score one vdpbf16ps chain over the pairs 0 .. k2 - 1
// in order; the keys that `lanes` selects are stored. Keys in registers: at most 16 pairs, unrolled so that
// kt stays there.
template <int kGroup, class Keys>
HNS_BF16_INLINE void score_group(const Dword* qb, ptrdiff_t q_dwords, int k2, const Keys& kt, __mmask16 lanes,
                                 float* out, ptrdiff_t ld) {
  __m512 acc[kGroup];
  for (int g = 0; g < kGroup; ++g) acc[g] = _mm512_setzero_ps();
  if constexpr (std::is_array_v<Keys>) {
#pragma GCC unroll 16
    for (int p = 0; p < 16; ++p)
      if (p < k2) score_step<kGroup>(qb + p, q_dwords, key_pairs(kt, p), acc);
  } else {
    for (int p = 0; p < k2; ++p) score_step<kGroup>(qb + p, q_dwords, key_pairs(kt, p), acc);
  }
  for (int g = 0; g < kGroup; ++g) _mm512_mask_storeu_ps(out + g * ld, lanes, acc[g]);
}

// m queries against one block of keys, four at a time (four independent chains), then the last one to three
// (each query's pairs q_dwords after the one before).
template <class Keys>
HNS_BF16_INLINE void score_queries(const Dword* qb, ptrdiff_t q_dwords, int m, int k2, const Keys& kt,
                                   __mmask16 lanes, float* out, ptrdiff_t ld) {
  int i = 0;
  for (; i + 4 <= m; i += 4) score_group<4>(qb + i * q_dwords, q_dwords, k2, kt, lanes, out + i * ld, ld);
  switch (m - i) {
    case 3:
      return score_group<3>(qb + i * q_dwords, q_dwords, k2, kt, lanes, out + i * ld, ld);
    case 2:
      return score_group<2>(qb + i * q_dwords, q_dwords, k2, kt, lanes, out + i * ld, ld);
    case 1:
      return score_group<1>(qb + i * q_dwords, q_dwords, k2, kt, lanes, out + i * ld, ld);
    default:
      return;
  }
}

// dh floats at x as bf16 pairs at out (k2 = dh / 2 dwords), 32 at a time.
HNS_BF16_INLINE void convert_pairs(const float* x, int dh, bf16_t* out) {
  for (int c = 0; c < dh; c += 32) {
    const __m512i v = cvt32_masked(x + c, dh - c);
    const int pairs_here = std::min(16, (dh - c) / 2);
    _mm512_mask_storeu_epi32(out + c, static_cast<__mmask16>((1u << pairs_here) - 1u), v);
  }
}

// attention_scores for at most 16 keys of at most 32 features (both models' heads have 32): the keys' pairs
// stay in registers after their transposition (the general path below stores them and loads them back for
// every group of queries), and each query's pairs are one vector on the stack, converted four at a time
// just before they are used (converting all of them first measured slower: 116 against 95 time-stamp cycles
// per call for 1-8 keys). The same chains, so the same bits; src/nn/README.md "The attention's scores with
// the keys in registers" has its speed.
HNS_BF16_INLINE void scores_in_registers(const float* q, ptrdiff_t q_stride, const float* k,
                                         ptrdiff_t k_stride, int m, int dh, float* out, ptrdiff_t ld) {
  const int k2 = dh / 2;
  __m512i kt[16];
#pragma GCC unroll 16
  for (int j = 0; j < 16; ++j) {
    const float* kj = k + j * k_stride;
    kt[j] = j < m ? cvt32_masked(kj, dh) : _mm512_setzero_si512();
  }
  transpose16(kt);
  const __mmask16 lanes = static_cast<__mmask16>((1u << m) - 1u);
  alignas(64) Dword qp[4 * 16];
  for (int i = 0; i < m; i += 4) {
    const int group = std::min(4, m - i);
    for (int g = 0; g < group; ++g) {
      const float* qi = q + (i + g) * q_stride;
      _mm512_store_si512(qp + g * 16, cvt32_masked(qi, dh));
    }
    score_queries(qp, 16, group, k2, kt, lanes, out + i * ld, ld);
  }
}

HNS_BF16_TARGET void attention_scores_avx512(const float* q, ptrdiff_t q_stride, const float* k,
                                             ptrdiff_t k_stride, int m, int dh, float* out, ptrdiff_t ld,
                                             bf16_t* scratch) {
  if (m <= 16 && dh <= 32) return scores_in_registers(q, q_stride, k, k_stride, m, dh, out, ld);
  const int k2 = dh / 2;
  bf16_t* qb = scratch;                                       // [m, k2] dwords
  bf16_t* kt = scratch + 2 * static_cast<ptrdiff_t>(m) * k2;  // [k2, 16] dwords: one block of keys
  for (int i = 0; i < m; ++i) convert_pairs(q + i * q_stride, dh, qb + 2 * static_cast<ptrdiff_t>(i) * k2);
  const Dword* q32 = reinterpret_cast<const Dword*>(qb);
  for (int j0 = 0; j0 < m; j0 += 16) {
    // 16 keys' pairs, converted as they are loaded, transposed in registers: kt's row p holds pair p of every
    // key of the block (the missing keys as zero lanes).
    const int keys = std::min(16, m - j0);
    for (int p0 = 0; p0 < k2; p0 += 16) {
      const int c0 = 2 * p0;
      // Unrolled, so that r stays in registers (a loop indexing it by a variable puts it on the stack).
      __m512i r[16];
#pragma GCC unroll 16
      for (int j = 0; j < 16; ++j) {
        const float* kj = k + (j0 + j) * k_stride + c0;
        r[j] = j < keys ? cvt32_masked(kj, dh - c0) : _mm512_setzero_si512();
      }
      transpose16(r);
      const int rows_here = std::min(16, k2 - p0);
#pragma GCC unroll 16
      for (int c = 0; c < 16; ++c)
        if (c < rows_here) _mm512_storeu_si512(kt + 2 * static_cast<ptrdiff_t>(p0 + c) * 16, r[c]);
    }
    score_queries(q32, k2, m, k2, kt, static_cast<__mmask16>((1u << keys) - 1u), out + j0, ld);
  }
}

// ---- packing

// Row pair (r0, r1) of B (r1 may be null: zeros), columns [0, n) as floats, into every panel's pair p (kp
// pairs per panel).
HNS_BF16_TARGET void pack_pair_rows(const float* r0, const float* r1, int n, int kp, int p, bf16_t* out) {
  // Panel by panel: a panel's 16-column vectors of pair p are consecutive (64 bytes each).
  for (int n0 = 0; n0 < n; n0 += kPanel) {
    const int width = panel_width(n, n0);
    const int whole = std::min(kPanel, n - n0) / kVecCols * kVecCols;  // columns in whole vectors
    const float* a = r0 + n0;
    const float* b = r1 != nullptr ? r1 + n0 : nullptr;
    bf16_t* dst = out + static_cast<ptrdiff_t>(n0) * 2 * kp + static_cast<ptrdiff_t>(p) * width * 2;
    int c = 0;
    if (b != nullptr)
      for (; c < whole; c += kVecCols)
        _mm512_storeu_si512(dst + 2 * c, cvt_pairs(_mm512_loadu_ps(a + c), _mm512_loadu_ps(b + c)));
    else
      for (; c < whole; c += kVecCols)
        _mm512_storeu_si512(dst + 2 * c, cvt_pairs(_mm512_loadu_ps(a + c), _mm512_setzero_ps()));
    if (c < width) {  // the last vector of the last panel: zeros past n
      const int count = n - n0 - c;
      const __m512 x1 = b != nullptr ? load_masked(b + c, count) : _mm512_setzero_ps();
      _mm512_storeu_si512(dst + 2 * c, cvt_pairs(load_masked(a + c, count), x1));
    }
  }
}

// Rows [0, k) of x (ldx floats apart), columns [0, n), into pairs [p0, p0 + (k + 1) / 2) of every panel (kp
// pairs per panel); an odd k's last pair has a zero row.
HNS_BF16_TARGET void pack_row_pairs(const float* x, ptrdiff_t ldx, int k, int n, int kp, int p0,
                                    bf16_t* out) {
  for (int p = 0; p < pairs(k); ++p) {
    const float* r0 = x + 2 * static_cast<ptrdiff_t>(p) * ldx;
    pack_pair_rows(r0, 2 * p + 1 < k ? r0 + ldx : nullptr, n, kp, p0 + p, out);
  }
}

// Zeros in the pairs [k2, kp) of every panel (the padding of k for AMX).
void zero_padding_pairs(int k2, int kp, int n, bf16_t* out) {
  if (kp == k2) return;
  for (int n0 = 0; n0 < n; n0 += kPanel) {
    const ptrdiff_t width = panel_width(n, n0);
    std::memset(out + n0 * 2 * ptrdiff_t(kp) + k2 * width * 2, 0,
                sizeof(bf16_t) * size_t((kp - k2) * width * 2));
  }
}

HNS_BF16_TARGET void pack_b_avx512(const float* w, ptrdiff_t ldw, int k, int n, bool transpose,
                                   const int* col_map, int kp, bf16_t* out) {
  const int k2 = pairs(k);
  zero_padding_pairs(k2, kp, n, out);
  // (pack_pair_rows writes whole vectors of 16 columns, zeros past n: the padding of the last panel.)
  if (!transpose && col_map == nullptr) return pack_row_pairs(w, ldw, k, n, kp, 0, out);
  if (transpose && col_map == nullptr) {
    // b's rows are w's columns. 16 of w's rows (b's columns j0 ..) times 16 of its columns (b's rows 2 p0 ..)
    // are transposed in registers, which gives b's rows over those 16 columns: converted in pairs, they are
    // one vector of each of 8 pairs of the panel. Rows of w past n and columns past k load as zeros: the
    // padding that pack_pair_rows writes.
    for (int j0 = 0; j0 < n; j0 += kVecCols) {
      const int count = std::min(kVecCols, n - j0);
      const int n0 = j0 / kPanel * kPanel;
      bf16_t* panel = out + static_cast<ptrdiff_t>(n0) * 2 * kp + 2 * (j0 - n0);
      const ptrdiff_t pair_elems = static_cast<ptrdiff_t>(panel_width(n, n0)) * 2;
      for (int p0 = 0; p0 < k2; p0 += 8) {
        const int cols = std::min(16, k - 2 * p0);  // w's columns in this block
        const __mmask16 col_mask = static_cast<__mmask16>((1u << cols) - 1u);
        __m512i r[16];
        for (int i = 0; i < 16; ++i)
          r[i] = i < count ? _mm512_maskz_loadu_epi32(col_mask, w + (j0 + i) * ldw + 2 * p0)
                           : _mm512_setzero_si512();
        transpose16(r);
        for (int q = 0; q < 8 && p0 + q < k2; ++q)
          _mm512_storeu_si512(panel + (p0 + q) * pair_elems,
                              cvt_pairs(_mm512_castsi512_ps(r[2 * q]), _mm512_castsi512_ps(r[2 * q + 1])));
      }
    }
    return;
  }
  if (n > kMaxGatherCols) throw std::length_error("bf16::pack_b: more than 4096 columns to gather");
  // General case: gather each row pair of b into two float rows first (b[i, j] = w[i, map(j)], or
  // w[j, map(i)] transposed).
  alignas(64) float row0[kMaxGatherCols];
  alignas(64) float row1[kMaxGatherCols];
  for (int p = 0; p < k2; ++p) {
    const int i0 = 2 * p, i1 = 2 * p + 1;
    if (transpose) {
      const ptrdiff_t c0 = col_map != nullptr ? col_map[i0] : i0;
      const ptrdiff_t c1 = i1 >= k ? -1 : col_map != nullptr ? col_map[i1] : i1;
      for (int j = 0; j < n; ++j) {
        row0[j] = w[j * ldw + c0];
        row1[j] = c1 >= 0 ? w[j * ldw + c1] : 0.0f;
      }
    } else {
      for (int j = 0; j < n; ++j) {
        const ptrdiff_t c = col_map != nullptr ? col_map[j] : j;
        row0[j] = w[i0 * ldw + c];
        row1[j] = i1 < k ? w[i1 * ldw + c] : 0.0f;
      }
    }
    pack_pair_rows(row0, row1, n, kp, p, out);
  }
}

// (lda: a multiple of 32 or k rounded up to even; padded_rows: rows and the zero rows after them)
HNS_BF16_TARGET void convert_a_avx512(const float* x, ptrdiff_t ldx, int rows, int k, ptrdiff_t lda,
                                      int padded_rows, bf16_t* out) {
  std::memset(out + rows * lda, 0, sizeof(bf16_t) * size_t((padded_rows - rows) * lda));
  for (int m = 0; m < rows; ++m) {
    const float* xr = x + m * ldx;
    bf16_t* o = out + m * lda;
    int j = 0;
    for (; j + 32 <= k; j += 32)
      _mm512_storeu_si512(o + j, cvt32(_mm512_loadu_ps(xr + j), _mm512_loadu_ps(xr + j + 16)));
    if (j < lda) {
      // The tail (and the zero that pads an odd k), masked: 32 bf16 at most.
      const __m512i v = cvt32_masked(xr + j, k - j);
      const int count = static_cast<int>(lda - j);
      _mm512_mask_storeu_epi16(o + j, static_cast<__mmask32>((uint64_t(1) << count) - 1u), v);
    }
  }
}

HNS_BF16_TARGET void convert_a_transposed_avx512(const float* x, ptrdiff_t ldx, int k, int rows,
                                                 bf16_t* out) {
  // Pair p of A's row m is (x[2p, m], x[2p + 1, m]): x's rows 2p and 2p + 1 interleaved, 16 columns at a
  // time, are 16 consecutive dwords of the pair-major layout.
  const int k2 = pairs(k);
  const ptrdiff_t ldm = transposed_rows(rows);
  for (int p = 0; p < k2; ++p) {
    const float* r0 = x + 2 * static_cast<ptrdiff_t>(p) * ldx;
    const float* r1 = 2 * p + 1 < k ? r0 + ldx : nullptr;
    bf16_t* o = out + 2 * static_cast<ptrdiff_t>(p) * ldm;
    for (int m0 = 0; m0 < rows; m0 += 16) {
      const int count = rows - m0;
      const __m512 x0 = load_masked(r0 + m0, count);
      const __m512 x1 = r1 != nullptr ? load_masked(r1 + m0, count) : _mm512_setzero_ps();
      _mm512_storeu_si512(o + 2 * m0, cvt_pairs(x0, x1));
    }
  }
}

// convert_a_transposed for AMX: whole tiles of 16 rows (x's columns) x 16 pairs (of x's rows).
HNS_BF16_TARGET void convert_a_tiles_avx512(const float* x, ptrdiff_t ldx, int k, int rows, bf16_t* out) {
  const int k2 = pairs(k);
  const int kp = round_up(k2, amx::kTilePairs);
  for (int m0 = 0; m0 < rows; m0 += amx::kTileRows) {
    const int count = rows - m0;
    for (int p0 = 0; p0 < kp; p0 += amx::kTilePairs) {
      __m512i r[16];  // r[i]: pair p0 + i of rows m0 .. m0 + 15
      for (int i = 0; i < 16; ++i) {
        const int p = p0 + i;
        if (p >= k2) {
          r[i] = _mm512_setzero_si512();
          continue;
        }
        const float* r0 = x + 2 * static_cast<ptrdiff_t>(p) * ldx + m0;
        const __m512 x0 = load_masked(r0, count);
        const __m512 x1 = 2 * p + 1 < k ? load_masked(r0 + ldx, count) : _mm512_setzero_ps();
        r[i] = cvt_pairs(x0, x1);
      }
      transpose16(r);
      bf16_t* tile = out + (static_cast<ptrdiff_t>(m0 / amx::kTileRows) * (kp / amx::kTilePairs) +
                            p0 / amx::kTilePairs) *
                               (amx::kTileRows * 2 * amx::kTilePairs);
      for (int i = 0; i < 16; ++i) _mm512_storeu_si512(tile + i * 2 * amx::kTilePairs, r[i]);
    }
  }
}

bool detect() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
         __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512dq") &&
         __builtin_cpu_supports("avx512bf16");
}

}  // namespace

bool available() {
  static const bool ok = detect();
  return ok;
}

bf16_t from_float(float x) {
  const uint32_t u = std::bit_cast<uint32_t>(flush_denormal(x));
  if (std::isnan(x)) return static_cast<bf16_t>((u >> 16) | 0x40u);
  return static_cast<bf16_t>((u + 0x7FFFu + ((u >> 16) & 1u)) >> 16);
}

float flush_denormal(float x) {
  return std::fpclassify(x) == FP_SUBNORMAL ? std::copysign(0.0f, x) : x;
}

float to_float(bf16_t x) {
  return std::bit_cast<float>(static_cast<uint32_t>(x) << 16);
}

const char* kernel_name(Kernel k) {
  switch (k) {
    case Kernel::kAmx:
      return "amx";
    case Kernel::kAmxEmulated:
      return "amx-emulated";
    default:
      return "avx512-bf16";
  }
}

bool amx_available() {
  return available() && amx::hardware_available();
}

Kernel kernel() {
  int k = g_kernel.load(std::memory_order_acquire);
  if (k >= 0) return static_cast<Kernel>(k);
  Kernel chosen = amx_available() ? Kernel::kAmx : Kernel::kAvx512Bf16;
  if (const char* env = std::getenv("HNS_BF16_KERNEL"); env != nullptr && *env != '\0') {
    const std::string v = env;
    if (v == "avx512-bf16") {
      chosen = Kernel::kAvx512Bf16;
    } else if (v == "amx") {
      if (!amx_available())
        throw std::invalid_argument("HNS_BF16_KERNEL=amx, but this CPU (or its OS) has no AMX-BF16 tiles");
      chosen = Kernel::kAmx;
    } else {
      throw std::invalid_argument("HNS_BF16_KERNEL='" + v + "' is not one of avx512-bf16, amx");
    }
  }
  g_kernel.store(static_cast<int>(chosen), std::memory_order_release);
  return chosen;
}

void set_kernel(Kernel k) {
  if (!available()) throw std::invalid_argument("bf16 kernels need AVX512-BF16, which this CPU lacks");
  if (k == Kernel::kAmx && !amx_available())
    throw std::invalid_argument("the amx kernel needs AMX-BF16 tiles, which this CPU (or its OS) lacks");
  g_kernel.store(static_cast<int>(k), std::memory_order_release);
}

size_t packed_elems(int k, int n) {
  return packed_pairs_elems(padded_pairs(k, kernel()), n);
}

size_t a_row_elems(int k) {
  return 2 * static_cast<size_t>(padded_pairs(k, kernel()));
}

size_t a_elems(int rows, int k) {
  return static_cast<size_t>(padded_rows(rows, kernel())) * a_row_elems(k);
}

void pack_b(const float* w, ptrdiff_t ldw, int k, int n, bool transpose, const int* col_map, bf16_t* out) {
  pack_b_avx512(w, ldw, k, n, transpose, col_map, padded_pairs(k, kernel()), out);
}

void convert_a(const float* x, ptrdiff_t ldx, int rows, int k, bf16_t* out) {
  const Kernel kern = kernel();
  convert_a_avx512(x, ldx, rows, k, static_cast<ptrdiff_t>(a_row_elems(k)), padded_rows(rows, kern), out);
}

size_t at_elems(int rows, int k) {
  const Kernel kern = kernel();
  if (tiles(kern)) return static_cast<size_t>(padded_rows(rows, kern)) * 2 * padded_pairs(k, kern);
  return 2 * static_cast<size_t>(pairs(k)) * static_cast<size_t>(transposed_rows(rows));
}

void convert_a_transposed(const float* x, ptrdiff_t ldx, int k, int rows, bf16_t* out) {
  if (tiles(kernel())) return convert_a_tiles_avx512(x, ldx, k, rows, out);
  convert_a_transposed_avx512(x, ldx, k, rows, out);
}

void gemm(const bf16_t* a, int rows, int k, const bf16_t* b, int n, float* c, ptrdiff_t ldc,
          bool accumulate) {
  const Kernel kern = kernel();
  if (tiles(kern)) {
    const ptrdiff_t lda = static_cast<ptrdiff_t>(a_row_elems(k));
    const amx::ATiles at{a, amx::kTileRows * lda, 2 * amx::kTilePairs, lda * ptrdiff_t(sizeof(bf16_t))};
    return amx::gemm(at, rows, padded_pairs(k, kern), b, n, c, ldc, accumulate, kern == Kernel::kAmxEmulated);
  }
  gemm_avx512(a, {pairs(k), 1}, rows, pairs(k), pairs(k), b, n, c, ldc, accumulate);
}

void gemm_bias(const bf16_t* a, int rows, int k, const bf16_t* b, int n, const float* bias, float* c,
               ptrdiff_t ldc) {
  if (tiles(kernel())) {  // the tiles start from C: C's rows set to the bias first
    for (int m = 0; m < rows; ++m) std::copy_n(bias, n, c + m * ldc);
    return gemm(a, rows, k, b, n, c, ldc, true);
  }
  gemm_avx512(a, {pairs(k), 1}, rows, pairs(k), pairs(k), b, n, c, ldc, false, bias);
}

void gemm_at(const bf16_t* at, int rows, int k, const bf16_t* b, int n, float* c, ptrdiff_t ldc,
             bool accumulate) {
  const Kernel kern = kernel();
  if (tiles(kern)) {
    const int kp = padded_pairs(k, kern);
    constexpr ptrdiff_t kTileElems = amx::kTileRows * 2 * amx::kTilePairs;
    const amx::ATiles a{at, kp / amx::kTilePairs * kTileElems, kTileElems, 2 * amx::kTilePairs * 2};
    return amx::gemm(a, rows, kp, b, n, c, ldc, accumulate, kern == Kernel::kAmxEmulated);
  }
  gemm_avx512(at, {1, transposed_rows(rows)}, rows, pairs(k), pairs(k), b, n, c, ldc, accumulate);
}

size_t at_pairs_elems(int rows, int kp) {
  return 2 * static_cast<size_t>(kp) * static_cast<size_t>(transposed_rows(rows));
}

size_t packed_pairs_elems(int kp, int n) {
  size_t total = 0;
  for (int n0 = 0; n0 < n; n0 += kPanel) total += static_cast<size_t>(panel_width(n, n0)) * 2 * kp;
  return total;
}

namespace {
void check_pairs(int k, int kp, int p0) {
  if (!available()) throw std::logic_error("bf16: pair blocks need AVX512-BF16, which this CPU lacks");
  if (p0 < 0 || p0 + pairs(k) > kp) throw std::invalid_argument("bf16: pairs past the block's kp");
}
}  // namespace

void convert_a_transposed_pairs(const float* x, ptrdiff_t ldx, int k, int rows, int kp, int p0, bf16_t* out) {
  check_pairs(k, kp, p0);
  convert_a_transposed_avx512(x, ldx, k, rows, out + 2 * static_cast<ptrdiff_t>(p0) * transposed_rows(rows));
}

void pack_b_rows_pairs(const float* x, ptrdiff_t ldx, int k, int n, int kp, int p0, bf16_t* out) {
  check_pairs(k, kp, p0);
  pack_row_pairs(x, ldx, k, n, kp, p0, out);
}

void gemm_at_pairs(const bf16_t* at, int rows, int k2, const bf16_t* b, int kp, int n, float* c,
                   ptrdiff_t ldc) {
  check_pairs(2 * k2, kp, 0);
  gemm_avx512(at, {1, transposed_rows(rows)}, rows, k2, kp, b, n, c, ldc, true);
}

size_t attention_scratch_elems(int m, int dh) {
  return 2 * static_cast<size_t>(pairs(dh)) * (static_cast<size_t>(m) + 16);
}

void attention_scores(const float* q, ptrdiff_t q_stride, const float* k, ptrdiff_t k_stride, int m, int dh,
                      float* out, ptrdiff_t ld, bf16_t* scratch) {
  if (!available() || tiles(kernel()) || dh % 2 != 0)
    throw std::logic_error(
        "attention_scores: the vdpbf16ps kernel (AVX512-BF16) and an even head width only");
  attention_scores_avx512(q, q_stride, k, k_stride, m, dh, out, ld, scratch);
}

bool rows_outer_order(bool accumulate, int rows, int k, int n) {
  return rows_outer(accumulate, rows, pairs(k), n);
}

void gemm_reference(const bf16_t* a, int rows, int k, const bf16_t* b, int n, float* c, ptrdiff_t ldc,
                    bool accumulate) {
  const int k2 = pairs(k);
  const int kp = padded_pairs(k, kernel());
  const ptrdiff_t lda = static_cast<ptrdiff_t>(a_row_elems(k));
  for (int m = 0; m < rows; ++m)
    for (int j = 0; j < n; ++j) {
      const int n0 = j / kPanel * kPanel;
      const bf16_t* panel = b + static_cast<ptrdiff_t>(n0) * 2 * kp;
      float acc = accumulate ? c[m * ldc + j] : 0.0f;
      for (int p = 0; p < k2; ++p) {
        const bf16_t* bp = panel + (static_cast<ptrdiff_t>(p) * panel_width(n, n0) + (j - n0)) * 2;
        const bf16_t* ap = a + m * lda + 2 * p;
        acc = flush_denormal(std::fma(flush_denormal(to_float(ap[1])), flush_denormal(to_float(bp[1])), acc));
        acc = flush_denormal(std::fma(flush_denormal(to_float(ap[0])), flush_denormal(to_float(bp[0])), acc));
      }
      c[m * ldc + j] = acc;
    }
}

}  // namespace hns::nn::bf16
