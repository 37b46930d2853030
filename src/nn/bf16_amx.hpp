// The AMX-BF16 tile product behind bf16::gemm and bf16::gemm_at (nn/bf16_gemm.hpp chooses it). Internal to
// hns_nn: callers use bf16_gemm.hpp.
//
// A tile is 16 rows of 64 bytes (16 floats, or 16 pairs of bf16). TDPBF16PS adds to a 16 x 16 float tile C
// the products of an A tile (16 rows of C x 16 pairs of k) and a B tile (16 pairs of k x 16 columns, each
// row the pairs (b[2p, n], b[2p + 1, n]) of 16 columns: exactly one k pair of a packed B panel). Per element
// of C, TDPBF16PS sums the tile's 16 pairs in two chains from 0, one of the even elements' products and one
// of the odd ones', each step rounded to nearest even with denormals flushed, then adds C + (even + odd):
// measured on a Xeon with AMX (bit for bit on every one of 102,400 random elements; the SDM's pseudocode
// reads (C + even) + odd, which matched 92 %). The emulation computes exactly that, and the tests hold the
// hardware to it bit for bit.
//
// Everything the kernel reads is padded, so it never needs a partial tile: k to whole blocks of 16 pairs
// (zeros in A and B), A's rows to whole blocks of 16. C's partial blocks (rows or columns past the edge)
// go through a 16 x 16 scratch tile, so nothing outside C is read or written.
#pragma once

#include <cstddef>
#include <cstdint>

namespace hns::nn::bf16::amx {

using bf16_t = uint16_t;

inline constexpr int kTileRows = 16;   // rows of a tile (of C and A)
inline constexpr int kTilePairs = 16;  // k pairs per A and B tile

// Whether this process can run AMX-BF16 tiles, and if not, why: the CPU lacks AMX-TILE or AMX-BF16, the OS
// does not save the tile state (XCR0: Linux before 5.16), or Linux refused this process the tile data
// (arch_prctl ARCH_REQ_XCOMP_PERM, asked once; a seccomp or container policy can refuse it).
enum class Support { kUsable, kNoCpu, kNoOs, kRefused };
Support support();
// True when support() is kUsable.
bool hardware_available();
// Why tiles the CPU has cannot run here, as a clause for the start line ("the OS ..."); empty for kUsable
// and kNoCpu.
const char* unusable_reason(Support s);

// Where A's tiles lie: the tile of row block rb and pair block pb starts at base + rb * row_block +
// pb * pair_block (in bf16 elements); its rows are stride_bytes apart.
struct ATiles {
  const bf16_t* base;
  ptrdiff_t row_block;
  ptrdiff_t pair_block;
  ptrdiff_t stride_bytes;
};

// C [rows, n] (row stride ldc) (+)= A B: A as `a` says (row blocks of 16 covering rows), B packed in panels
// of 64 columns with kp pairs (a multiple of 16) per panel (bf16_gemm.hpp's layout). emulate: the same
// arithmetic in scalar code on any CPU (tests of the layouts on machines without AMX).
void gemm(const ATiles& a, int rows, int kp, const bf16_t* b, int n, float* c, ptrdiff_t ldc, bool accumulate,
          bool emulate);

}  // namespace hns::nn::bf16::amx
