// The AMX-BF16 tile product (nn/bf16_amx.hpp). The tile instructions are written as inline assembly with the
// tile number an immediate, so this file builds with the library's flags and runs them only where
// hardware_available(); the same kernel template runs on an emulation of the tiles for the tests.
#include "nn/bf16_amx.hpp"

#include <cpuid.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "nn/bf16_gemm.hpp"

namespace hns::nn::bf16::amx {
namespace {

constexpr int kTileBytes = 64;  // bytes per tile row

// ---- the tiles on hardware

// The tile configuration (palette 1): tiles 0-7 all 16 rows of 64 bytes. Loaded at each product's start.
struct alignas(64) TileConfig {
  uint8_t palette = 1;
  uint8_t start_row = 0;
  uint8_t reserved[14] = {};
  uint16_t colsb[16] = {};
  uint8_t rows[16] = {};
  TileConfig() {
    for (int t = 0; t < 8; ++t) {
      colsb[t] = kTileBytes;
      rows[t] = kTileRows;
    }
  }
};
static_assert(sizeof(TileConfig) == 64);

struct Hardware {
  // Loaded at the start of every product and released at its end, so other AMX code on the thread (a
  // library's) finds the tiles as it left them, and the OS saves no tile data for an idle thread.
  static void configure() {
    static const TileConfig config;
    asm volatile("ldtilecfg %0" ::"m"(config));
  }
  static void release() { asm volatile("tilerelease" ::); }
  template <int T>
  static void load(const void* p, ptrdiff_t stride) {
    asm volatile("tileloadd (%0,%1,1), %%tmm%c2" ::"r"(p), "r"(stride), "i"(T) : "memory");
  }
  template <int T>
  static void store(void* p, ptrdiff_t stride) {
    asm volatile("tilestored %%tmm%c2, (%0,%1,1)" ::"r"(p), "r"(stride), "i"(T) : "memory");
  }
  template <int T>
  static void zero() {
    asm volatile("tilezero %%tmm%c0" ::"i"(T));
  }
  // C += A B (AT&T operand order: B, A, C).
  template <int C, int A, int B>
  static void dp() {
    asm volatile("tdpbf16ps %%tmm%c2, %%tmm%c1, %%tmm%c0" ::"i"(C), "i"(A), "i"(B));
  }
};

// ---- the same tiles in scalar code

struct Emulated {
  struct Tiles {
    alignas(64) unsigned char t[8][kTileRows][kTileBytes];
  };
  static Tiles& tiles() {
    thread_local Tiles state;
    return state;
  }
  static void configure() {}
  static void release() {}
  template <int T>
  static void load(const void* p, ptrdiff_t stride) {
    for (int r = 0; r < kTileRows; ++r)
      std::memcpy(tiles().t[T][r], static_cast<const unsigned char*>(p) + r * stride, kTileBytes);
  }
  template <int T>
  static void store(void* p, ptrdiff_t stride) {
    for (int r = 0; r < kTileRows; ++r)
      std::memcpy(static_cast<unsigned char*>(p) + r * stride, tiles().t[T][r], kTileBytes);
  }
  template <int T>
  static void zero() {
    std::memset(tiles().t[T], 0, sizeof(tiles().t[T]));
  }
  // TDPBF16PS as the hardware computes it: per element of C, the even elements' products of the 16 pairs in
  // one chain from 0 and the odd elements' in another (each step rounded to nearest even, denormals
  // flushed), then C + (even + odd). (Intel's SDM reads (C + even) + odd; a Xeon with AMX matched this
  // order on all of 102,400 random elements and the SDM's on 92 %.)
  template <int C, int A, int B>
  static void dp() {
    float c[kTileRows][16];
    bf16_t a[kTileRows][2 * kTilePairs], b[kTilePairs][32];
    std::memcpy(c, tiles().t[C], sizeof(c));
    std::memcpy(a, tiles().t[A], sizeof(a));
    std::memcpy(b, tiles().t[B], sizeof(b));
    for (int m = 0; m < kTileRows; ++m)
      for (int n = 0; n < 16; ++n) {
        float even = 0.0f, odd = 0.0f;
        for (int p = 0; p < kTilePairs; ++p) {
          even = flush_denormal(
              std::fma(flush_denormal(to_float(a[m][2 * p])), flush_denormal(to_float(b[p][2 * n])), even));
          odd = flush_denormal(std::fma(flush_denormal(to_float(a[m][2 * p + 1])),
                                        flush_denormal(to_float(b[p][2 * n + 1])), odd));
        }
        c[m][n] = flush_denormal(c[m][n] + flush_denormal(even + odd));
      }
    std::memcpy(tiles().t[C], c, sizeof(c));
  }
};

// ---- the kernel

// One C tile's place: vr x vc valid elements at c. A partial tile goes through a 16 x 16 scratch, filled
// (before any tile instruction) and emptied (after the last) by plain code, so no call runs while tiles
// hold data.
struct CTile {
  float* c;
  int vr, vc;
  bool full() const { return vr == kTileRows && vc == 16; }
  void fill(ptrdiff_t ldc, bool accumulate, float* scratch) const {
    if (!accumulate || full()) return;
    std::memset(scratch, 0, kTileRows * kTileBytes);
    for (int r = 0; r < vr; ++r) std::memcpy(scratch + r * 16, c + r * ldc, sizeof(float) * size_t(vc));
  }
  void empty(ptrdiff_t ldc, const float* scratch) const {
    if (full()) return;
    for (int r = 0; r < vr; ++r) std::memcpy(c + r * ldc, scratch + r * 16, sizeof(float) * size_t(vc));
  }
};
template <class T, int Tile>
void c_load(const CTile& t, ptrdiff_t ldc, bool accumulate, float* scratch) {
  if (!accumulate) return T::template zero<Tile>();
  if (t.full()) return T::template load<Tile>(t.c, ldc * ptrdiff_t(sizeof(float)));
  T::template load<Tile>(scratch, kTileBytes);
}
template <class T, int Tile>
void c_store(const CTile& t, ptrdiff_t ldc, float* scratch) {
  if (t.full()) return T::template store<Tile>(t.c, ldc * ptrdiff_t(sizeof(float)));
  T::template store<Tile>(scratch, kTileBytes);
}

// kRows row blocks x kCols column vectors of C (tiles 0, 1 / 2, 3), A in tiles 4 and 5, B in 6 and 7.
// c: C's element (16 rb, n0 + 16 v); rows_left / cols_left: C's rows and columns from there.
template <class T, int kRows, int kCols>
void block(const ATiles& a, int rb, const bf16_t* panel, int width, int v, int kp, float* c, ptrdiff_t ldc,
           int rows_left, int cols_left, bool accumulate) {
  alignas(64) float scratch[4][kTileRows * 16];
  const int vr0 = std::min(kTileRows, rows_left), vc0 = std::min(16, cols_left);
  // (tiles 1-3 exist only where kCols / kRows say so; their places are then inside C)
  const int vr1 = kRows == 2 ? std::min(kTileRows, rows_left - kTileRows) : 0;
  const int vc1 = kCols == 2 ? std::min(16, cols_left - 16) : 0;
  const CTile t[4] = {{c, vr0, vc0},
                      {kCols == 2 ? c + 16 : c, vr0, vc1},
                      {kRows == 2 ? c + kTileRows * ldc : c, vr1, vc0},
                      {kRows == 2 ? c + kTileRows * ldc + 16 : c, vr1, vc1}};
  t[0].fill(ldc, accumulate, scratch[0]);
  if constexpr (kCols == 2) t[1].fill(ldc, accumulate, scratch[1]);
  if constexpr (kRows == 2) t[2].fill(ldc, accumulate, scratch[2]);
  if constexpr (kRows == 2 && kCols == 2) t[3].fill(ldc, accumulate, scratch[3]);
  c_load<T, 0>(t[0], ldc, accumulate, scratch[0]);
  if constexpr (kCols == 2) c_load<T, 1>(t[1], ldc, accumulate, scratch[1]);
  if constexpr (kRows == 2) c_load<T, 2>(t[2], ldc, accumulate, scratch[2]);
  if constexpr (kRows == 2 && kCols == 2) c_load<T, 3>(t[3], ldc, accumulate, scratch[3]);
  const ptrdiff_t ldb_bytes = ptrdiff_t(width) * 2 * ptrdiff_t(sizeof(bf16_t));
  const bf16_t* a0 = a.base + rb * a.row_block;
  const bf16_t* b0 = panel + ptrdiff_t(v) * kVecCols * 2;
  for (int pb = 0; pb < kp / kTilePairs; ++pb) {
    const bf16_t* ap = a0 + pb * a.pair_block;
    const bf16_t* bp = b0 + ptrdiff_t(pb) * kTilePairs * width * 2;
    T::template load<4>(ap, a.stride_bytes);
    if constexpr (kRows == 2) T::template load<5>(ap + a.row_block, a.stride_bytes);
    T::template load<6>(bp, ldb_bytes);
    if constexpr (kCols == 2) T::template load<7>(bp + kVecCols * 2, ldb_bytes);
    T::template dp<0, 4, 6>();
    if constexpr (kCols == 2) T::template dp<1, 4, 7>();
    if constexpr (kRows == 2) T::template dp<2, 5, 6>();
    if constexpr (kRows == 2 && kCols == 2) T::template dp<3, 5, 7>();
  }
  c_store<T, 0>(t[0], ldc, scratch[0]);
  if constexpr (kCols == 2) c_store<T, 1>(t[1], ldc, scratch[1]);
  if constexpr (kRows == 2) c_store<T, 2>(t[2], ldc, scratch[2]);
  if constexpr (kRows == 2 && kCols == 2) c_store<T, 3>(t[3], ldc, scratch[3]);
  t[0].empty(ldc, scratch[0]);
  if constexpr (kCols == 2) t[1].empty(ldc, scratch[1]);
  if constexpr (kRows == 2) t[2].empty(ldc, scratch[2]);
  if constexpr (kRows == 2 && kCols == 2) t[3].empty(ldc, scratch[3]);
}

template <class T>
void gemm_tiles(const ATiles& a, int rows, int kp, const bf16_t* b, int n, float* c, ptrdiff_t ldc,
                bool accumulate) {
  T::configure();
  const int row_blocks = (rows + kTileRows - 1) / kTileRows;
  // Two row blocks of A at a time, across every panel of B (A stays in L1, B streams from L2).
  for (int rb = 0; rb < row_blocks; rb += 2) {
    const bool two_rows = rb + 1 < row_blocks;
    const int rows_left = rows - rb * kTileRows;
    for (int n0 = 0; n0 < n; n0 += kPanel) {
      const int width = panel_width(n, n0);
      const int vecs = width / kVecCols;
      const bf16_t* panel = b + ptrdiff_t(n0) * 2 * kp;
      for (int v = 0; v < vecs; v += 2) {
        const bool two_cols = v + 1 < vecs;
        float* cb = c + ptrdiff_t(rb) * kTileRows * ldc + n0 + v * kVecCols;
        const int cols_left = n - n0 - v * kVecCols;
        if (two_rows && two_cols) {
          block<T, 2, 2>(a, rb, panel, width, v, kp, cb, ldc, rows_left, cols_left, accumulate);
        } else if (two_rows) {
          block<T, 2, 1>(a, rb, panel, width, v, kp, cb, ldc, rows_left, cols_left, accumulate);
        } else if (two_cols) {
          block<T, 1, 2>(a, rb, panel, width, v, kp, cb, ldc, rows_left, cols_left, accumulate);
        } else {
          block<T, 1, 1>(a, rb, panel, width, v, kp, cb, ldc, rows_left, cols_left, accumulate);
        }
      }
    }
  }
  T::release();
}

Support detect() {
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  if (__get_cpuid_count(7, 0, &eax, &ebx, &ecx, &edx) == 0) return Support::kNoCpu;
  if (((edx >> 24) & 1u) == 0 || ((edx >> 22) & 1u) == 0) return Support::kNoCpu;  // AMX-TILE, AMX-BF16
  // The CPU has the tiles; the OS must save their state (OSXSAVE, then XCR0's tile bits).
  if (__get_cpuid(1, &eax, &ebx, &ecx, &edx) == 0 || ((ecx >> 27) & 1u) == 0) return Support::kNoOs;
  uint32_t xcr0_lo = 0, xcr0_hi = 0;
  asm volatile("xgetbv" : "=a"(xcr0_lo), "=d"(xcr0_hi) : "c"(0));
  constexpr uint32_t kTileState = (1u << 17) | (1u << 18);  // XTILECFG, XTILEDATA
  if ((xcr0_lo & kTileState) != kTileState) return Support::kNoOs;
  // Linux hands out the 8 KiB tile data state per process on request.
  constexpr long kArchReqXcompPerm = 0x1023, kXfeatureXtiledata = 18;
  return syscall(SYS_arch_prctl, kArchReqXcompPerm, kXfeatureXtiledata) == 0 ? Support::kUsable
                                                                             : Support::kRefused;
}

}  // namespace

Support support() {
  static const Support s = detect();
  return s;
}

bool hardware_available() {
  return support() == Support::kUsable;
}

const char* unusable_reason(Support s) {
  switch (s) {
    case Support::kNoOs:
      return "the OS does not enable their state (XCR0; Linux 5.16 or later does)";
    case Support::kRefused:
      return "Linux refused this process their state (arch_prctl ARCH_REQ_XCOMP_PERM; a seccomp or container "
             "policy may forbid it)";
    default:
      return "";
  }
}

void gemm(const ATiles& a, int rows, int kp, const bf16_t* b, int n, float* c, ptrdiff_t ldc, bool accumulate,
          bool emulate) {
  if (rows <= 0 || n <= 0) return;
  if (emulate) return gemm_tiles<Emulated>(a, rows, kp, b, n, c, ldc, accumulate);
  gemm_tiles<Hardware>(a, rows, kp, b, n, c, ldc, accumulate);
}

}  // namespace hns::nn::bf16::amx
