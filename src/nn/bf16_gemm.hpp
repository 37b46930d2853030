// Mixed-precision matrix products: bfloat16 operands (float rounded to nearest even), float accumulation,
// float results, on AVX512-BF16's vdpbf16ps (chosen at run time: this code is compiled for the CPU's
// extension by function attributes, so the library itself still runs on any CPU of its build's instruction
// set; callers check available() first).
//
// Data layout:
// - A (the left operand) is bf16 row-major with its k padded to an even count (k2 = pairs, a row is 2 * k2
//   elements, the last one 0 when k is odd): each vdpbf16ps takes one pair of a row (a 32-bit broadcast).
// - B (the right operand) is packed into panels of kPanel = 64 columns (the last panel zero-padded to a
//   multiple of 16); within a panel, k pair p holds, for each column n, (b[2p, n], b[2p + 1, n]): four
//   vectors of 16 columns x 2.
// - C[m, n] = (accumulate ? C[m, n] : 0) + sum over pairs p in order of
//   (a[m, 2p] b[2p, n] + a[m, 2p + 1] b[2p + 1, n]), as vdpbf16ps computes it. Each element is one chain
//   over k in order, whatever the number of rows: a row's result does not depend on the rows beside it.
//
// Nothing here allocates; the per-thread scratch of the float-level helpers in layers.cpp grows to its
// largest shape once.
#pragma once

#include <cstddef>
#include <cstdint>

namespace hns::nn::bf16 {

using bf16_t = uint16_t;

inline constexpr int kPanel = 64;    // columns per packed panel
inline constexpr int kVecCols = 16;  // columns per vector

// True when this CPU runs the kernels (AVX512-BF16 and the vector state enabled by the OS).
bool available();

// Float to bf16, round to nearest even (NaN stays NaN), and back (exact).
bf16_t from_float(float x);
float to_float(bf16_t x);

// Elements of a packed B of k rows and n columns.
size_t packed_elems(int k, int n);
// Elements of an A of `rows` rows and k columns (k padded to even).
inline size_t a_elems(int rows, int k) {
  return static_cast<size_t>(rows) * static_cast<size_t>((k + 1) / 2 * 2);
}

// B [k, n] from float w: b = w (w [k, n], row stride ldw) or, with transpose, b = w^T (w [n, k]). A
// col_map reorders w's columns first: b[i, j] = w[i, col_map[j]], or w[j, col_map[i]] transposed.
void pack_b(const float* w, ptrdiff_t ldw, int k, int n, bool transpose, const int* col_map, bf16_t* out);
// A [rows, k] from float x (row stride ldx).
void convert_a(const float* x, ptrdiff_t ldx, int rows, int k, bf16_t* out);
// A = x^T for x [k, rows] (row stride ldx), in the pair-major layout gemm_at reads: pair p of A's row m is
// the dword at p * ldm + m (ldm = rows rounded up to 16), i.e. x's rows 2p and 2p + 1 interleaved, written
// with whole-vector stores (no transposition). at_elems of them.
size_t at_elems(int rows, int k);
void convert_a_transposed(const float* x, ptrdiff_t ldx, int k, int rows, bf16_t* out);
// B [k, n] from float activations (row stride ldx), packed as pack_b without transpose.
inline void pack_b_rows(const float* x, ptrdiff_t ldx, int k, int n, bf16_t* out) {
  pack_b(x, ldx, k, n, false, nullptr, out);
}

// C [rows, n] (row stride ldc) (+)= A [rows, k] B [k, n].
void gemm(const bf16_t* a, int rows, int k, const bf16_t* b, int n, float* c, ptrdiff_t ldc, bool accumulate);
// The same with A from convert_a_transposed (the weight gradients: C = x^T B).
void gemm_at(const bf16_t* at, int rows, int k, const bf16_t* b, int n, float* c, ptrdiff_t ldc,
             bool accumulate);

// The scalar reference of gemm: the same rounding of the operands and the same pair order per element
// (fmaf of the odd element of a pair, then of the even one; denormal products and sums flushed to zero as
// vdpbf16ps does). Used by the tests.
void gemm_reference(const bf16_t* a, int rows, int k, const bf16_t* b, int n, float* c, ptrdiff_t ldc,
                    bool accumulate);

}  // namespace hns::nn::bf16
