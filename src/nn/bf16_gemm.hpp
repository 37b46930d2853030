// Mixed-precision matrix products: bfloat16 operands (float rounded to nearest even), float accumulation,
// float results. Two kernels, chosen at run time (kernel()): AMX-BF16 tiles where the CPU has them and
// AVX512-BF16's vdpbf16ps otherwise. This code is compiled for the CPU's extensions by function attributes
// and inline assembly, so the library itself still runs on any CPU of its build's instruction set; callers
// check available() first.
//
// Data layout (k2 = k's pairs, kp = k2 padded to the kernel's pair block: 1 for vdpbf16ps, 16 for AMX):
// - A (the left operand) is bf16 row-major, a row a_row_elems(k) = 2 kp elements (zeros past k): each
//   vdpbf16ps takes one pair of a row (a 32-bit broadcast), each AMX tile 16 pairs of 16 rows. For AMX the
//   rows are padded (with zero rows) to a multiple of 16, a_elems counts them.
// - B (the right operand) is packed into panels of kPanel = 64 columns (the last panel zero-padded to a
//   multiple of 16); within a panel, k pair p (p < kp, zeros past k) holds, for each column n,
//   (b[2p, n], b[2p + 1, n]): four vectors of 16 columns x 2, and 16 such pairs are one AMX B tile.
// - C[m, n] = (accumulate ? C[m, n] : 0) + the products over k, summed in an order fixed per element:
//   vdpbf16ps adds, pair by pair, the odd element's product then the even one's, each with one rounding;
//   an AMX tile, per block of 16 pairs, sums the even elements' products in one chain from 0 and the odd
//   ones' in another, then adds C + (even + odd). Either way the order depends on k alone, whatever the
//   number of rows: a row's result does not depend on the rows beside it (and so not on the thread count).
//
// Nothing here allocates; the per-thread scratch of the float-level helpers in products.cpp grows to its
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

// The product kernels. kAmxEmulated is the AMX kernel's exact arithmetic on scalar code: it checks the AMX
// layouts on any CPU with AVX512-BF16 (tests only; slow).
enum class Kernel { kAvx512Bf16, kAmx, kAmxEmulated };
// "avx512-bf16", "amx", "amx-emulated".
const char* kernel_name(Kernel k);
// True when this CPU and OS run AMX-BF16 tiles (cpuid, XCR0, and Linux's permission for the tile state).
bool amx_available();
// The kernel in use: AMX where amx_available(), else AVX512-BF16. The environment variable
// HNS_BF16_KERNEL=avx512-bf16 or amx chooses one (to compare them on one machine); read until it gives a
// usable choice: an unknown value, or amx without AMX, throws std::invalid_argument naming it.
Kernel kernel();
// Switch kernels (tests and benchmarks), while no product runs. The layouts below depend on the kernel:
// convert and pack again after a switch (PackedWeights::pack lays its storage out anew). Throws
// std::invalid_argument for a kernel this CPU cannot run.
void set_kernel(Kernel k);

// Float to bf16, round to nearest even (NaN stays NaN), and back (exact).
bf16_t from_float(float x);
float to_float(bf16_t x);
// A denormal as a zero of its sign, anything else as it is (how the bf16 instructions treat denormals).
float flush_denormal(float x);

// Columns the packed panel starting at column n0 (a multiple of kPanel) of n holds: kPanel, or the last
// panel's columns rounded up to whole vectors.
inline int panel_width(int n, int n0) {
  const int w = n - n0 < kPanel ? n - n0 : kPanel;
  return (w + kVecCols - 1) / kVecCols * kVecCols;
}

// Elements of a packed B of k rows and n columns.
size_t packed_elems(int k, int n);
// Elements of one row of A of k columns (2 kp), and of an A of `rows` rows (rows padded for AMX).
size_t a_row_elems(int k);
size_t a_elems(int rows, int k);

// B [k, n] from float w: b = w (w [k, n], row stride ldw) or, with transpose, b = w^T (w [n, k]). A
// col_map reorders w's columns first: b[i, j] = w[i, col_map[j]], or w[j, col_map[i]] transposed.
void pack_b(const float* w, ptrdiff_t ldw, int k, int n, bool transpose, const int* col_map, bf16_t* out);
// A [rows, k] from float x (row stride ldx).
void convert_a(const float* x, ptrdiff_t ldx, int rows, int k, bf16_t* out);
// A = x^T for x [k, rows] (row stride ldx), in the layout gemm_at reads, at_elems of them. For vdpbf16ps
// pair-major: pair p of A's row m is the dword at p * ldm + m (ldm = rows rounded up to 16), i.e. x's rows
// 2p and 2p + 1 interleaved, written with whole-vector stores (no transposition). For AMX whole tiles: the
// tile of rows [16 i, 16 i + 16) and pairs [16 j, 16 j + 16) is 512 consecutive elements at
// (i * kp / 16 + j) * 512, row by row (16 pairs of x's columns transposed), zeros past rows and k.
size_t at_elems(int rows, int k);
void convert_a_transposed(const float* x, ptrdiff_t ldx, int k, int rows, bf16_t* out);
// B [k, n] from float activations (row stride ldx), packed as pack_b without transpose.
inline void pack_b_rows(const float* x, ptrdiff_t ldx, int k, int n, bf16_t* out) {
  pack_b(x, ldx, k, n, false, nullptr, out);
}

// C [rows, n] (row stride ldc) (+)= A [rows, k] B [k, n].
void gemm(const bf16_t* a, int rows, int k, const bf16_t* b, int n, float* c, ptrdiff_t ldc, bool accumulate);
// C [rows, n] = bias + A B, the bias [n] (not null) in every row: the same bits as C's rows set to the bias
// and gemm accumulating; the vdpbf16ps kernel starts its sums from the bias in registers instead of that
// pass over C (the AMX kernels, whose tiles start from C, make it).
void gemm_bias(const bf16_t* a, int rows, int k, const bf16_t* b, int n, const float* bias, float* c,
               ptrdiff_t ldc);
// The same as gemm with A from convert_a_transposed (the weight gradients: C = x^T B).
void gemm_at(const bf16_t* at, int rows, int k, const bf16_t* b, int n, float* c, ptrdiff_t ldc,
             bool accumulate);

// Weight gradients summed over several blocks of rows in one product, in the vdpbf16ps kernel's layout and
// arithmetic whichever kernel() is in use (they need AVX512-BF16 only). C (+)= x^T B is a chain over k's
// pairs in order, so the blocks' pairs laid end to end in one A and one B and summed by one product give the
// bits of the vdpbf16ps kernel's gemm_at per block, block after block, with fewer passes over C. A holds kp
// pairs of `rows` rows (at_pairs_elems; pair p of row m is the dword at p * ldm + m, as convert_a_transposed
// lays it out), B kp pairs per panel (packed_pairs_elems). A block of k rows of x (and of the B rows) goes
// into pairs [p0, p0 + (k + 1) / 2), an odd k's last pair padded with zeros as gemm_at's would be;
// gemm_at_pairs sums pairs [0, k2) into C.
size_t at_pairs_elems(int rows, int kp);
size_t packed_pairs_elems(int kp, int n);
void convert_a_transposed_pairs(const float* x, ptrdiff_t ldx, int k, int rows, int kp, int p0, bf16_t* out);
void pack_b_rows_pairs(const float* x, ptrdiff_t ldx, int k, int n, int kp, int p0, bf16_t* out);
void gemm_at_pairs(const bf16_t* at, int rows, int k2, const bf16_t* b, int kp, int n, float* c,
                   ptrdiff_t ldc);

// The attention's scores for one head (nn/attention.cpp), with the vdpbf16ps kernel only (std::logic_error
// under the AMX kernels, on a CPU without AVX512-BF16, or for an odd dh): out[i * ld + j] for i, j < m is the
// bf16 product of query i (dh floats at q + i * q_stride) and key j (at k + j * k_stride), one vdpbf16ps
// chain over the pairs in order, as gemm sums an element; nothing else of out is written. The operands are
// converted as they are read and the keys transposed in registers, 16 at a time; scratch holds
// attention_scratch_elems(m, dh) elements.
size_t attention_scratch_elems(int m, int dh);
void attention_scores(const float* q, ptrdiff_t q_stride, const float* k, ptrdiff_t k_stride, int m, int dh,
                      float* out, ptrdiff_t ld, bf16_t* scratch);

// True where the vdpbf16ps kernel takes C's tiles row tile by row tile across the panels rather than panel
// by panel (an accumulating product into a C over 512 KB with a B of at most 512 KB); the sums are the same
// either way. For the tests, which check that their shapes reach that order.
bool rows_outer_order(bool accumulate, int rows, int k, int n);

// The scalar reference of the vdpbf16ps kernel: the same rounding of the operands and the same pair order
// per element (fmaf of the odd element of a pair, then of the even one; denormal products and sums flushed
// to zero as vdpbf16ps does). Reads the current kernel's layouts. Used by the tests.
void gemm_reference(const bf16_t* a, int rows, int k, const bf16_t* b, int n, float* c, ptrdiff_t ldc,
                    bool accumulate);

}  // namespace hns::nn::bf16
