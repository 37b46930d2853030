// The bf16 products (issue 31): conversion, packing and both kernels (vdpbf16ps, AMX tiles: on hardware where
// the CPU has them, and the AMX kernel's emulation everywhere) against scalar references, the layers'
// product helpers against float, and the precision chooser.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "nn/bf16_amx.hpp"
#include "nn/bf16_gemm.hpp"
#include "nn/kernels.hpp"
#include "nn/layers.hpp"
#include "nn/precision.hpp"
#include "nn/products.hpp"

namespace hns::nn {
namespace bf16 {
void PrintTo(Kernel k, std::ostream* os) {
  *os << kernel_name(k);
}
}  // namespace bf16
namespace {

using bf16::bf16_t;

std::vector<float> random_floats(size_t n, uint32_t seed, float scale = 1.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-scale, scale);
  std::vector<float> v(n);
  for (float& x : v) x = u(rng);
  return v;
}

constexpr bf16_t kNan = 0x7FC0;  // a bf16 quiet NaN: what unwritten operand memory holds in the tests

float bf(float x) {
  return bf16::to_float(bf16::from_float(x));
}

// C[m, j] from unpacked float operands a [rows, k], b [k, n] in the kernel's documented order, operands
// rounded to bf16 (the independent statement of what gemm computes; no packing involved):
// - vdpbf16ps (amx false): per pair (2p, 2p + 1) of k, fmaf of the odd element, then of the even one;
// - AMX (amx true): per block of 16 pairs (zeros past k), the even elements' products in one fmaf chain from
//   0 and the odd ones' in another, then C + (even + odd) (TDPBF16PS as a Xeon with AMX computes it).
void naive_product(const std::vector<float>& a, const std::vector<float>& b, int rows, int k, int n,
                   std::vector<float>& c, bool accumulate, bool amx = false) {
  auto at = [&](const std::vector<float>& v, size_t i, bool inside) { return inside ? bf(v[i]) : 0.0f; };
  for (int m = 0; m < rows; ++m)
    for (int j = 0; j < n; ++j) {
      float acc = accumulate ? c[size_t(m) * n + j] : 0.0f;
      if (!amx) {
        for (int p = 0; 2 * p < k; ++p) {
          const int i0 = 2 * p, i1 = 2 * p + 1;
          if (i1 < k) acc = std::fma(bf(a[size_t(m) * k + i1]), bf(b[size_t(i1) * n + j]), acc);
          acc = std::fma(bf(a[size_t(m) * k + i0]), bf(b[size_t(i0) * n + j]), acc);
        }
      } else {
        for (int p0 = 0; 2 * p0 < k; p0 += 16) {
          float even = 0.0f, odd = 0.0f;
          for (int p = p0; p < p0 + 16; ++p) {
            const int i0 = 2 * p, i1 = 2 * p + 1;
            even = std::fma(at(a, size_t(m) * k + i0, i0 < k), at(b, size_t(i0) * n + j, i0 < k), even);
            odd = std::fma(at(a, size_t(m) * k + i1, i1 < k), at(b, size_t(i1) * n + j, i1 < k), odd);
          }
          acc = acc + (even + odd);
        }
      }
      c[size_t(m) * n + j] = acc;
    }
}

// The kernels under test: vdpbf16ps, the AMX kernel's emulation (both where the CPU has AVX512-BF16) and
// the AMX hardware (where it has the tiles). Each test switches to its kernel and back.
class NnBf16Kernel : public ::testing::TestWithParam<bf16::Kernel> {
 protected:
  void SetUp() override {
    if (!bf16::available()) GTEST_SKIP() << "this CPU has no AVX512-BF16: the bf16 kernels cannot run here";
    if (GetParam() == bf16::Kernel::kAmx && !bf16::amx_available())
      GTEST_SKIP() << "this CPU has no AMX-BF16 tiles";
    saved_ = bf16::kernel();
    bf16::set_kernel(GetParam());
    switched_ = true;
  }
  void TearDown() override {
    if (switched_) bf16::set_kernel(saved_);
  }
  bool amx() const { return GetParam() != bf16::Kernel::kAvx512Bf16; }
  // got against the documented arithmetic (want, from naive_product), bit for bit: every kernel, the AMX
  // hardware included (a CPU whose tiles rounded otherwise fails here rather than passing silently).
  static void expect_product(float got, float want, const std::string& where) {
    ASSERT_EQ(std::bit_cast<uint32_t>(got), std::bit_cast<uint32_t>(want))
        << where << ": " << got << " vs " << want;
  }

 private:
  bf16::Kernel saved_ = bf16::Kernel::kAvx512Bf16;
  bool switched_ = false;
};
INSTANTIATE_TEST_SUITE_P(Kernels, NnBf16Kernel,
                         ::testing::Values(bf16::Kernel::kAvx512Bf16, bf16::Kernel::kAmxEmulated,
                                           bf16::Kernel::kAmx),
                         [](const ::testing::TestParamInfo<bf16::Kernel>& info) {
                           std::string name = bf16::kernel_name(info.param);
                           for (char& ch : name)
                             if (ch == '-') ch = '_';
                           return name;
                         });

TEST(NnBf16, RoundsToNearestEvenAndKeepsSpecialValues) {
  // 1 + 2^-8 is halfway between 1 and 1 + 2^-7: ties go to the even mantissa (1); 1 + 3 * 2^-8 rounds up.
  EXPECT_EQ(bf(1.0f + 0x1p-8f), 1.0f);
  EXPECT_EQ(bf(1.0f + 3 * 0x1p-8f), 1.0f + 0x1p-6f);
  EXPECT_EQ(bf(1.0f + 0x1p-8f + 0x1p-20f), 1.0f + 0x1p-7f);
  EXPECT_EQ(bf(-2.5f), -2.5f);
  EXPECT_TRUE(std::isnan(bf(std::numeric_limits<float>::quiet_NaN())));
  EXPECT_EQ(bf(std::numeric_limits<float>::infinity()), std::numeric_limits<float>::infinity());
  EXPECT_EQ(bf(3.4e38f), std::numeric_limits<float>::infinity());  // above bf16's largest finite value
  EXPECT_EQ(bf(1e-40f), 0.0f);                                     // denormals flush to zero
  EXPECT_TRUE(std::signbit(bf(-1e-40f)));
}

TEST_P(NnBf16Kernel, VectorConversionEqualsScalarForEveryLengthAndSpecialValues) {
  std::vector<float> x = random_floats(3 * 71, 1, 100.0f);
  const float specials[] = {0.0f,
                            -0.0f,
                            1.0f + 0x1p-8f,
                            1.0f + 3 * 0x1p-8f,
                            1e-40f,
                            -1e-40f,
                            3.4e38f,
                            std::numeric_limits<float>::infinity(),
                            -std::numeric_limits<float>::infinity(),
                            std::numeric_limits<float>::quiet_NaN()};
  for (size_t i = 0; i < std::size(specials); ++i) x[7 * i + 3] = specials[i];
  for (int k = 1; k <= 71; ++k) {
    const int rows = 3;
    std::vector<bf16_t> a(bf16::a_elems(rows, k), 0xFFFF);
    bf16::convert_a(x.data(), 71, rows, k, a.data());
    const int lda = int(bf16::a_row_elems(k));
    ASSERT_EQ(lda, amx() ? (k + 31) / 32 * 32 : (k + 1) / 2 * 2);
    ASSERT_EQ(bf16::a_elems(rows, k), size_t(lda) * (amx() ? 16 : rows));
    for (int m = 0; m < int(bf16::a_elems(rows, k)) / lda; ++m) {
      if (m >= rows) {
        for (int i = 0; i < lda; ++i) ASSERT_EQ(a[size_t(m) * lda + i], 0) << "padding row " << m;
        continue;
      }
      for (int i = 0; i < k; ++i) {
        const float v = x[size_t(m) * 71 + i];
        const bf16_t want = bf16::from_float(v);
        if (std::isnan(v)) {
          EXPECT_TRUE(std::isnan(bf16::to_float(a[size_t(m) * lda + i])));
        } else {
          ASSERT_EQ(a[size_t(m) * lda + i], want)
              << "k " << k << " row " << m << " col " << i << " value " << v;
        }
      }
      for (int i = k; i < lda; ++i) ASSERT_EQ(a[size_t(m) * lda + i], 0) << "the padding of k is 0";
    }
  }
}

TEST_P(NnBf16Kernel, KernelMatchesTheScalarReferenceBitForBitForOddShapes) {
  const int ks[] = {1, 2, 3, 17, 32, 33, 64, 255};
  const int ns[] = {1, 15, 16, 17, 37, 63, 64, 65, 130, 256};
  uint32_t seed = 10;
  for (int k : ks)
    for (int n : ns)
      for (int rows : {1, 2, 4, 5, 6, 7, 8, 13, 16, 17, 33}) {  // every remainder of the 6-row tile
        const std::vector<float> a = random_floats(size_t(rows) * k, ++seed);
        const std::vector<float> w = random_floats(size_t(k) * n, ++seed);
        // Operand buffers full of NaN first: every element the kernel reads, padding included, is written.
        std::vector<bf16_t> ab(bf16::a_elems(rows, k), kNan), bb(bf16::packed_elems(k, n), kNan);
        bf16::convert_a(a.data(), k, rows, k, ab.data());
        bf16::pack_b(w.data(), n, k, n, false, nullptr, bb.data());
        for (bool acc : {false, true}) {
          // Output rows wider than n (stride n + 3) with sentinels between, and two sentinel rows after C:
          // nothing outside C is written.
          const int ldc = n + 3;
          std::vector<float> c0 = random_floats(size_t(rows + 2) * ldc, ++seed);
          std::vector<float> c1 = c0, c2 = c0;
          bf16::gemm(ab.data(), rows, k, bb.data(), n, c1.data(), ldc, acc);
          if (!amx()) bf16::gemm_reference(ab.data(), rows, k, bb.data(), n, c2.data(), ldc, acc);
          std::vector<float> want(size_t(rows) * n);
          for (int m = 0; m < rows; ++m)
            for (int j = 0; j < n; ++j) want[size_t(m) * n + j] = c0[size_t(m) * ldc + j];
          naive_product(a, w, rows, k, n, want, acc, amx());
          for (size_t i = size_t(rows) * ldc; i < c0.size(); ++i)
            ASSERT_EQ(std::bit_cast<uint32_t>(c1[i]), std::bit_cast<uint32_t>(c0[i]))
                << "wrote past the rows";
          for (int m = 0; m < rows; ++m)
            for (int j = 0; j < ldc; ++j) {
              const size_t i = size_t(m) * ldc + j;
              if (j >= n) {
                ASSERT_EQ(std::bit_cast<uint32_t>(c1[i]), std::bit_cast<uint32_t>(c0[i])) << "wrote past n";
                continue;
              }
              if (!amx()) {
                ASSERT_EQ(std::bit_cast<uint32_t>(c1[i]), std::bit_cast<uint32_t>(c2[i]))
                    << "kernel vs reference, rows " << rows << " k " << k << " n " << n << " at " << m << ","
                    << j;
              }
              ASSERT_NO_FATAL_FAILURE(expect_product(c1[i], want[size_t(m) * n + j],
                                                     "kernel vs unpacked product, rows " +
                                                         std::to_string(rows) + " k " + std::to_string(k) +
                                                         " n " + std::to_string(n)));
            }
        }
      }
}

// A product that starts from a bias (rows::dense_forward's y = b + x W) has the bits of C's rows set to the
// bias and the product accumulated into them, and writes nothing outside C: odd shapes, and one whose C is
// large enough that the accumulating product takes its other tile order.
TEST_P(NnBf16Kernel, ProductFromABiasEqualsBiasRowsThenAccumulating) {
  struct Shape {
    int rows, k, n;
  };
  std::vector<Shape> shapes;
  for (int k : {1, 3, 32, 33, 160})
    for (int n : {1, 16, 17, 63, 130})
      for (int rows : {1, 6, 7, 17}) shapes.push_back({rows, k, n});
  shapes.push_back({300, 160, 600});
  ASSERT_TRUE(bf16::rows_outer_order(true, 300, 160, 600)) << "the large shape must take the other order";
  uint32_t seed = 500;
  for (const Shape& s : shapes) {
    const std::vector<float> a = random_floats(size_t(s.rows) * s.k, ++seed);
    const std::vector<float> w = random_floats(size_t(s.k) * s.n, ++seed);
    const std::vector<float> bias = random_floats(size_t(s.n), ++seed);
    std::vector<bf16_t> ab(bf16::a_elems(s.rows, s.k)), bb(bf16::packed_elems(s.k, s.n));
    bf16::convert_a(a.data(), s.k, s.rows, s.k, ab.data());
    bf16::pack_b(w.data(), s.n, s.k, s.n, false, nullptr, bb.data());
    const int ldc = s.n + 3;  // sentinels between the rows and two rows after C
    const std::vector<float> c0 = random_floats(size_t(s.rows + 2) * ldc, ++seed);
    std::vector<float> from_bias = c0, filled = c0;
    bf16::gemm_bias(ab.data(), s.rows, s.k, bb.data(), s.n, bias.data(), from_bias.data(), ldc);
    for (int m = 0; m < s.rows; ++m) std::copy(bias.begin(), bias.end(), filled.begin() + size_t(m) * ldc);
    bf16::gemm(ab.data(), s.rows, s.k, bb.data(), s.n, filled.data(), ldc, true);
    for (size_t i = 0; i < c0.size(); ++i)
      ASSERT_EQ(std::bit_cast<uint32_t>(from_bias[i]), std::bit_cast<uint32_t>(filled[i]))
          << "rows " << s.rows << " k " << s.k << " n " << s.n << " at " << i / size_t(ldc) << ","
          << i % size_t(ldc);
  }
}

TEST_P(NnBf16Kernel, ARowsResultDoesNotDependOnTheRowsBesideIt) {
  const int k = 129, n = 200, rows = 37;
  const std::vector<float> a = random_floats(size_t(rows) * k, 3);
  const std::vector<float> w = random_floats(size_t(k) * n, 4);
  std::vector<bf16_t> ab(bf16::a_elems(rows, k)), bb(bf16::packed_elems(k, n));
  bf16::convert_a(a.data(), k, rows, k, ab.data());
  bf16::pack_b(w.data(), n, k, n, false, nullptr, bb.data());
  std::vector<float> all(size_t(rows) * n);
  bf16::gemm(ab.data(), rows, k, bb.data(), n, all.data(), n, false);
  for (int m = 0; m < rows; ++m) {
    // Row m alone, and row m among other rows at another place of the tiles (rows 3 .. 3 + m).
    std::vector<bf16_t> a1(bf16::a_elems(1, k)), a2(bf16::a_elems(m + 4, k));
    bf16::convert_a(a.data() + size_t(m) * k, k, 1, k, a1.data());
    std::vector<float> shifted(size_t(m + 4) * k);
    for (size_t i = 0; i < shifted.size(); ++i) shifted[i] = a[(i + size_t(rows - 3) * k) % a.size()];
    bf16::convert_a(shifted.data(), k, m + 4, k, a2.data());
    std::vector<float> one(n), among(size_t(m + 4) * n);
    bf16::gemm(a1.data(), 1, k, bb.data(), n, one.data(), n, false);
    bf16::gemm(a2.data(), m + 4, k, bb.data(), n, among.data(), n, false);
    ASSERT_EQ(std::memcmp(one.data(), among.data() + size_t(m + 3) * n, sizeof(float) * n), 0) << "row " << m;
    ASSERT_EQ(std::memcmp(one.data(), all.data() + size_t(m) * n, sizeof(float) * n), 0) << "row " << m;
  }
}

TEST_P(NnBf16Kernel, TransposedAndReorderedPackingMatchesTheirDefinition) {
  const int k = 37, n = 70, rows = 4;
  const std::vector<float> a = random_floats(size_t(rows) * k, 5);
  // w_t [n, k]: b = w_t^T; w_m [k, n] with its columns reversed: b[i, j] = w_m[i, n - 1 - j].
  const std::vector<float> w_t = random_floats(size_t(n) * k, 6);
  const std::vector<float> w_m = random_floats(size_t(k) * n, 7);
  std::vector<int> reverse(n);
  for (int j = 0; j < n; ++j) reverse[j] = n - 1 - j;
  std::vector<bf16_t> ab(bf16::a_elems(rows, k), kNan), bb(bf16::packed_elems(k, n), kNan);
  bf16::convert_a(a.data(), k, rows, k, ab.data());
  std::vector<float> b(size_t(k) * n), got(size_t(rows) * n), want(size_t(rows) * n);
  for (int pass = 0; pass < 3; ++pass) {
    for (int i = 0; i < k; ++i)
      for (int j = 0; j < n; ++j)
        b[size_t(i) * n + j] = pass == 0   ? w_t[size_t(j) * k + i]
                               : pass == 1 ? w_m[size_t(i) * n + (n - 1 - j)]
                                           : w_t[size_t(j) * k + (k - 1 - i)];
    if (pass == 0) bf16::pack_b(w_t.data(), k, k, n, true, nullptr, bb.data());
    if (pass == 1) bf16::pack_b(w_m.data(), n, k, n, false, reverse.data(), bb.data());
    if (pass == 2) {
      // transposed with a map: b[i, j] = w_t[j, map(i)], map reversing k
      std::vector<int> rk(k);
      for (int i = 0; i < k; ++i) rk[i] = k - 1 - i;
      bf16::pack_b(w_t.data(), k, k, n, true, rk.data(), bb.data());
    }
    bf16::gemm(ab.data(), rows, k, bb.data(), n, got.data(), n, false);
    naive_product(a, b, rows, k, n, want, false, amx());
    for (size_t i = 0; i < got.size(); ++i)
      ASSERT_NO_FATAL_FAILURE(expect_product(got[i], want[i], "pass " + std::to_string(pass)));
  }
}

// Packing w [n, k] (row stride ldw) transposed gives, byte for byte, the packing of its transpose b = w^T
// written out: every pair, every panel, and the zeros past k and past n. Shapes around the 16 x 16 blocks
// that the transposed packing works in, and the panels of 64 columns.
TEST_P(NnBf16Kernel, TransposedPackingEqualsPackingTheTransposeBitForBit) {
  for (int k : {1, 2, 15, 16, 17, 33, 37, 64})
    for (int n : {1, 15, 16, 17, 64, 70, 130}) {
      const int ldw = k + 3;
      const std::vector<float> w = random_floats(size_t(n) * ldw, uint32_t(k * 1000 + n));
      std::vector<float> b(size_t(k) * n);
      for (int i = 0; i < k; ++i)
        for (int j = 0; j < n; ++j) b[size_t(i) * n + j] = w[size_t(j) * ldw + i];
      std::vector<bf16_t> want(bf16::packed_elems(k, n), kNan), got(bf16::packed_elems(k, n), kNan);
      bf16::pack_b(b.data(), n, k, n, false, nullptr, want.data());
      bf16::pack_b(w.data(), ldw, k, n, true, nullptr, got.data());
      ASSERT_EQ(want, got) << "k " << k << ", n " << n;
    }
}

TEST_P(NnBf16Kernel, TransposedProductMatchesItsDefinition) {
  // C = x^T B for x [k, rows] with a row stride (the weight gradient's form), for row counts around the
  // layout's vectors and tiles of 16 and k around AMX's blocks of 16 pairs.
  for (int k : {1, 2, 7, 40, 65})
    for (int rows : {1, 6, 15, 16, 17, 45})
      for (int n : {5, 64, 70}) {
        const int ldx = rows + 5;
        const std::vector<float> x = random_floats(size_t(k) * ldx, uint32_t(k * 100 + rows));
        const std::vector<float> w = random_floats(size_t(k) * n, uint32_t(n));
        std::vector<float> a(size_t(rows) * k);  // x^T, unpacked
        for (int m = 0; m < rows; ++m)
          for (int i = 0; i < k; ++i) a[size_t(m) * k + i] = x[size_t(i) * ldx + m];
        std::vector<bf16_t> at(bf16::at_elems(rows, k), kNan), bb(bf16::packed_elems(k, n), kNan);
        bf16::convert_a_transposed(x.data(), ldx, k, rows, at.data());
        bf16::pack_b(w.data(), n, k, n, false, nullptr, bb.data());
        std::vector<float> got = random_floats(size_t(rows) * n, 3), want = got;
        bf16::gemm_at(at.data(), rows, k, bb.data(), n, got.data(), n, true);
        naive_product(a, w, rows, k, n, want, true, amx());
        for (size_t i = 0; i < got.size(); ++i)
          ASSERT_NO_FATAL_FAILURE(expect_product(
              got[i], want[i],
              "k " + std::to_string(k) + " rows " + std::to_string(rows) + " n " + std::to_string(n)));
      }
}

// Blocks of rows laid end to end (convert_a_transposed_pairs, pack_b_rows_pairs) and summed by one
// gemm_at_pairs: the bits of the vdpbf16ps kernel's gemm_at per block, block after block, odd blocks' zero
// pair included, for row counts around the layout's vectors and B panels of several widths; under every
// kernel (the pair blocks are the vdpbf16ps kernel's layout and arithmetic whichever kernel is in use).
TEST_P(NnBf16Kernel, ProductOverBlocksOfPairsEqualsOneProductPerBlock) {
  const bf16::Kernel param = GetParam();
  // gemm_at per block, the reference, on the vdpbf16ps kernel.
  auto one_product = [&](const std::vector<float>& x, int ldx, const std::vector<float>& dz, int k, int rows,
                         int n, std::vector<float>& c) {
    bf16::set_kernel(bf16::Kernel::kAvx512Bf16);
    std::vector<bf16_t> a1(bf16::at_elems(rows, k), kNan), b1(bf16::packed_elems(k, n), kNan);
    bf16::convert_a_transposed(x.data(), ldx, k, rows, a1.data());
    bf16::pack_b_rows(dz.data(), n + 2, k, n, b1.data());
    bf16::gemm_at(a1.data(), rows, k, b1.data(), n, c.data(), n, true);
    bf16::set_kernel(param);
  };
  const int kp = 48;
  const int blocks[] = {40, 7, 1, 20, 26};  // 20 + 4 + 1 + 10 + 13 = 48 pairs
  for (int rows : {1, 6, 17, 45})
    for (int n : {5, 64, 130}) {
      SCOPED_TRACE(::testing::Message() << "rows " << rows << " n " << n);
      std::vector<bf16_t> at(bf16::at_pairs_elems(rows, kp), kNan), bb(bf16::packed_pairs_elems(kp, n), kNan);
      std::vector<float> want = random_floats(size_t(rows) * n, 3), got = want;
      std::vector<float> first = random_floats(size_t(rows) * n, 5), first_want = first;
      int p0 = 0;
      for (int i = 0; i < 5; ++i) {
        const int k = blocks[i], ldx = rows + 3;
        const std::vector<float> x = random_floats(size_t(k) * ldx, uint32_t(100 * i + rows));
        const std::vector<float> dz = random_floats(size_t(k) * (n + 2), uint32_t(7 * i + n));
        one_product(x, ldx, dz, k, rows, n, want);
        if (i == 0) one_product(x, ldx, dz, k, rows, n, first_want);
        bf16::convert_a_transposed_pairs(x.data(), ldx, k, rows, kp, p0, at.data());
        bf16::pack_b_rows_pairs(dz.data(), n + 2, k, n, kp, p0, bb.data());
        p0 += (k + 1) / 2;
      }
      ASSERT_EQ(p0, kp);
      bf16::gemm_at_pairs(at.data(), rows, kp, bb.data(), kp, n, got.data(), n);
      for (size_t i = 0; i < got.size(); ++i) ASSERT_NO_FATAL_FAILURE(expect_product(got[i], want[i], "C"));
      // The first block's pairs only: the panels are read at their kp-pair stride.
      bf16::gemm_at_pairs(at.data(), rows, 20, bb.data(), kp, n, first.data(), n);
      for (size_t i = 0; i < first.size(); ++i)
        ASSERT_NO_FATAL_FAILURE(expect_product(first[i], first_want[i], "the first block's pairs"));
    }
  std::vector<bf16_t> at(bf16::at_pairs_elems(6, 4));
  EXPECT_THROW(bf16::convert_a_transposed_pairs(nullptr, 6, 7, 6, 4, 1, at.data()), std::invalid_argument)
      << "a block past kp pairs";
}

// Accumulating products into a C larger than 512 KB with a B of at most 512 KB: the vdpbf16ps kernel takes
// its tiles row by row across the panels there (a cold gradient buffer, as the LSTM's weight gradients meet
// it) instead of panel by panel. Every element, the last partial row tile and the last narrow panel
// included, is still the documented sum, for both forms of A.
TEST_P(NnBf16Kernel, LargeAccumulatingProductsMatchTheirDefinition) {
  struct Shape {
    bool transposed;
    int rows, k, n;
  };
  // C: 143 x 1000 and 139 x 1030 floats (559 and 559 KiB); B: 19 x 1000 and 17 x 1030 pairs (74 and 68 KiB).
  for (const Shape s : {Shape{false, 143, 37, 1000}, Shape{true, 139, 33, 1030}}) {
    ASSERT_TRUE(bf16::rows_outer_order(true, s.rows, s.k, s.n)) << "the shapes no longer reach that order";
    const std::vector<float> x = random_floats(size_t(s.rows) * s.k, uint32_t(s.rows));
    const std::vector<float> w = random_floats(size_t(s.k) * s.n, uint32_t(s.n));
    std::vector<float> a(size_t(s.rows) * s.k);  // A unpacked, [rows, k]
    std::vector<bf16_t> ab, bb(bf16::packed_elems(s.k, s.n), kNan);
    if (s.transposed) {
      // x holds A^T [k, rows], as a layer's input does for its weight gradient.
      for (int m = 0; m < s.rows; ++m)
        for (int i = 0; i < s.k; ++i) a[size_t(m) * s.k + i] = x[size_t(i) * s.rows + m];
      ab.assign(bf16::at_elems(s.rows, s.k), kNan);
      bf16::convert_a_transposed(x.data(), s.rows, s.k, s.rows, ab.data());
    } else {
      a = x;
      ab.assign(bf16::a_elems(s.rows, s.k), kNan);
      bf16::convert_a(x.data(), s.k, s.rows, s.k, ab.data());
    }
    bf16::pack_b(w.data(), s.n, s.k, s.n, false, nullptr, bb.data());
    std::vector<float> got = random_floats(size_t(s.rows) * s.n, 11), want = got;
    if (s.transposed) {
      bf16::gemm_at(ab.data(), s.rows, s.k, bb.data(), s.n, got.data(), s.n, true);
    } else {
      bf16::gemm(ab.data(), s.rows, s.k, bb.data(), s.n, got.data(), s.n, true);
    }
    naive_product(a, w, s.rows, s.k, s.n, want, true, amx());
    for (size_t i = 0; i < got.size(); ++i)
      ASSERT_NO_FATAL_FAILURE(expect_product(got[i], want[i],
                                             std::string(s.transposed ? "gemm_at" : "gemm") + " at " +
                                                 std::to_string(i / s.n) + "," + std::to_string(i % s.n)));
  }
}

// The layers' three product forms in bf16 stay within the bf16 rounding bound of the float products:
// |bf16 - float| <= 2 * 2^-8 * sum_k |a_k b_k| + k * 2^-24 * that sum (operand rounding of both operands,
// then float accumulation).
TEST_P(NnBf16Kernel, LayerProductsStayWithinTheRoundingBoundOfFloat) {
  ParamLayout layout;
  const int in = 45, out = 77, rows = 19;
  const size_t w_off = layout.add_kernel_normal("w", in, out, 1.0f);
  const int id = layout.add_product({w_off, in, out, {}});
  ParamStore store(layout);
  store.init(3);
  PackedWeights packed(store.layout());
  packed.pack(store.values(), true);
  const Weights fp32(store.values()), b16(store.values(), &packed);
  const float* w = store.values() + w_off;
  const std::vector<float> x = random_floats(size_t(rows) * in, 8);
  const std::vector<float> dz = random_floats(size_t(rows) * out, 9);
  auto check = [&](const std::vector<float>& got, const std::vector<float>& want,
                   const std::vector<float>& mag, int k, const char* what) {
    for (size_t i = 0; i < got.size(); ++i) {
      const double bound = (2 * 0x1p-8 + k * 0x1p-24) * mag[i] + 1e-30;
      ASSERT_LE(std::fabs(double(got[i]) - want[i]), bound) << what << " at " << i;
    }
  };
  {  // y = x W
    std::vector<float> y1(size_t(rows) * out), y2(y1.size()), mag(y1.size());
    matmul(fp32, id, w, CMat(x.data(), rows, in), Mat(y1.data(), rows, out), false);
    matmul(b16, id, w, CMat(x.data(), rows, in), Mat(y2.data(), rows, out), false);
    for (int m = 0; m < rows; ++m)
      for (int j = 0; j < out; ++j)
        for (int i = 0; i < in; ++i)
          mag[size_t(m) * out + j] += std::fabs(x[size_t(m) * in + i] * w[size_t(i) * out + j]);
    check(y2, y1, mag, in, "x W");
  }
  {  // dx = dz W^T
    std::vector<float> d1(size_t(rows) * in), d2(d1.size()), mag(d1.size());
    matmul_t(fp32, id, w, CMat(dz.data(), rows, out), Mat(d1.data(), rows, in), false);
    matmul_t(b16, id, w, CMat(dz.data(), rows, out), Mat(d2.data(), rows, in), false);
    for (int m = 0; m < rows; ++m)
      for (int i = 0; i < in; ++i)
        for (int j = 0; j < out; ++j)
          mag[size_t(m) * in + i] += std::fabs(dz[size_t(m) * out + j] * w[size_t(i) * out + j]);
    check(d2, d1, mag, out, "dz W^T");
  }
  {  // dW = x^T dz
    std::vector<float> g1(size_t(in) * out), g2(g1.size()), mag(g1.size());
    matmul_grad(fp32, CMat(x.data(), rows, in), CMat(dz.data(), rows, out), g1.data(), false);
    matmul_grad(b16, CMat(x.data(), rows, in), CMat(dz.data(), rows, out), g2.data(), false);
    for (int i = 0; i < in; ++i)
      for (int j = 0; j < out; ++j)
        for (int m = 0; m < rows; ++m)
          mag[size_t(i) * out + j] += std::fabs(x[size_t(m) * in + i] * dz[size_t(m) * out + j]);
    check(g2, g1, mag, rows, "x^T dz");
  }
}

// The attention's scores for one head (nn/attention.cpp): queries and keys read from float rows a stride
// apart make the documented bf16 product, for key counts around the 16-key blocks and head widths around a
// block of 16 pairs (so both paths: at most 16 keys of at most 32 features in registers, the rest through
// the scratch), every remainder of the four-query groups; nothing past the m columns of a score row is
// written. The AMX kernels refuse it (the attention keeps float scores there), and so does an odd head width.
TEST_P(NnBf16Kernel, AttentionScoresMatchTheirDefinition) {
  std::vector<bf16_t> scratch(bf16::attention_scratch_elems(2, 2), kNan);
  if (amx()) {
    std::vector<float> x(64), c(4);
    EXPECT_THROW(bf16::attention_scores(x.data(), 2, x.data(), 2, 2, 2, c.data(), 2, scratch.data()),
                 std::logic_error);
    return;
  }
  for (int dh : {2, 8, 30, 32, 34, 64})
    for (int m : {1, 2, 3, 4, 5, 6, 15, 16, 17, 33, 70}) {
      // Queries at column 2 and keys at column 4 + dh of m rows of cols floats (a head's slices of q and k).
      const int cols = 2 * dh + 7, ldc = m + 3;
      const std::vector<float> x = random_floats(size_t(m) * cols, uint32_t(dh * 1000 + m));
      std::vector<float> got(size_t(m) * ldc, 777.0f), want(size_t(m) * m);
      // Scratch of exactly the stated size, NaN, then canaries that must survive.
      const size_t need = bf16::attention_scratch_elems(m, dh);
      scratch.assign(need + 512, kNan);
      std::fill(scratch.begin() + ptrdiff_t(need), scratch.end(), bf16_t{0x1234});
      bf16::attention_scores(x.data() + 2, cols, x.data() + 4 + dh, cols, m, dh, got.data(), ldc,
                             scratch.data());
      for (size_t e = need; e < scratch.size(); ++e) ASSERT_EQ(scratch[e], 0x1234) << "past the scratch";
      std::vector<float> q(size_t(m) * dh), keys_t(size_t(dh) * m);
      for (int i = 0; i < m; ++i)
        for (int c = 0; c < dh; ++c) {
          q[size_t(i) * dh + c] = x[size_t(i) * cols + 2 + c];
          keys_t[size_t(c) * m + i] = x[size_t(i) * cols + 4 + dh + c];
        }
      naive_product(q, keys_t, m, dh, m, want, false);
      const std::string where = "dh " + std::to_string(dh) + " m " + std::to_string(m);
      for (int i = 0; i < m; ++i) {
        for (int j = 0; j < m; ++j)
          ASSERT_NO_FATAL_FAILURE(expect_product(got[size_t(i) * ldc + j], want[size_t(i) * m + j], where));
        for (int j = m; j < ldc; ++j) ASSERT_EQ(got[size_t(i) * ldc + j], 777.0f) << where;
      }
    }
  std::vector<float> x(16), c(4);
  EXPECT_THROW(bf16::attention_scores(x.data(), 3, x.data(), 3, 2, 3, c.data(), 2, scratch.data()),
               std::logic_error);
}

// In a bf16 network the attention layer's probabilities are the softmax of those bf16 products of its own
// queries and keys with the vdpbf16ps kernel, and of float fma chains (as in fp32) under the AMX kernels: two
// heads of 32 features, rows with up to 20 keys (more than a 16-key block), some entities masked. The
// backward pass's scores (da·v, the probabilities' gradient before the softmax) are the same product: after
// it, the score buffer holds those of the last row (which sees all 20 entities) and head.
TEST_P(NnBf16Kernel, AttentionScoresInBothPassesAreTheKernelsProducts) {
  const int rows = 3, e_count = 20, d = 64, heads = 2, dh = d / heads;
  ParamLayout layout;
  SelfAttention sa(layout, "a", d, heads, true, true);
  ParamStore store(layout);
  store.init(5);
  PackedWeights packed(store.layout());
  packed.pack(store.values(), true);
  const Weights w16(store.values(), &packed);
  std::vector<float> mask = random_floats(size_t(rows) * e_count, 6);
  for (float& v : mask) v = v < 0.3f ? 1.0f : 0.0f;
  mask[0] = mask[e_count] = 1.0f;
  for (int e = 0; e < e_count; ++e) mask[size_t(2) * e_count + e] = 1.0f;  // a row that sees every entity
  const std::vector<float> x = random_floats(size_t(rows) * e_count * d, 7);
  Workspace<SelfAttention::Buffers> ws(rows, e_count, d, heads);
  std::vector<float> y(x.size());
  sa.forward(w16, CMat(x.data(), rows * e_count, d), mask.data(), e_count, ws.bufs(),
             Mat(y.data(), rows * e_count, d));
  const SelfAttention::Buffers& b = ws.bufs();
  // One score as the kernel in use defines it: a bf16 chain over pairs, or a float fma chain under AMX.
  auto score = [&](const float* a, const float* k) {
    std::vector<float> av(a, a + dh), kv(k, k + dh), one(1, 0.0f);
    if (amx()) {
      for (int c = 0; c < dh; ++c) one[0] = std::fma(a[c], k[c], one[0]);
    } else {
      naive_product(av, kv, 1, dh, 1, one, false);
    }
    return one[0];
  };
  const std::vector<float> ones(e_count, 1.0f);
  std::vector<float> scores(e_count), want(e_count);
  for (int r = 0; r < rows; ++r) {
    const int c0 = b.offset[r], m = b.offset[r + 1] - c0;
    for (int h = 0; h < heads; ++h)
      for (int i = 0; i < m; ++i) {
        for (int j = 0; j < m; ++j)
          scores[size_t(j)] =
              score(b.qk + size_t(c0 + i) * 2 * d + h * dh, b.qk + size_t(c0 + j) * 2 * d + d + h * dh);
        kernels::masked_softmax(scores.data(), ones.data(), 1.0f / std::sqrt(float(dh)), m, want.data());
        const float* got = b.probs + (size_t(r) * heads + h) * e_count * e_count + size_t(i) * e_count;
        for (int j = 0; j < m; ++j)
          ASSERT_EQ(std::bit_cast<uint32_t>(got[j]), std::bit_cast<uint32_t>(want[size_t(j)]))
              << "row " << r << " head " << h << " query " << i << " key " << j;
      }
  }
  const std::vector<float> dout = random_floats(y.size(), 8);
  std::vector<float> dx(x.size());
  sa.backward(w16, store.grads(), CMat(x.data(), rows * e_count, d), mask.data(), e_count, ws.bufs(),
              CMat(y.data(), rows * e_count, d), CMat(dout.data(), rows * e_count, d),
              Mat(dx.data(), rows * e_count, d));
  const int r = rows - 1, h = heads - 1, c0 = b.offset[r], m = b.offset[r + 1] - c0;
  ASSERT_EQ(m, e_count);
  const int ld = attention_key_stride(m);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) {
      const float want_ij = score(b.d_att + size_t(c0 + i) * d + h * dh, b.v + size_t(c0 + j) * d + h * dh);
      ASSERT_EQ(std::bit_cast<uint32_t>(b.scores[size_t(i) * ld + j]), std::bit_cast<uint32_t>(want_ij))
          << "backward, query " << i << " key " << j;
    }
}

TEST(NnPrecision, ChooserRefusesBf16WithoutTheFeatureAndResolvesAuto) {
  CpuFeatures none;
  CpuFeatures with;
  with.avx512_bf16 = true;
  EXPECT_EQ(resolve_precision("fp32", none), Precision::kFp32);
  EXPECT_EQ(resolve_precision("auto", none), Precision::kFp32);
  EXPECT_EQ(resolve_precision("auto", with), Precision::kBf16);
  EXPECT_EQ(resolve_precision("bf16", with), Precision::kBf16);
  try {
    resolve_precision("bf16", none);
    FAIL() << "bf16 accepted on a CPU without AVX512-BF16";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("AVX512-BF16"), std::string::npos) << e.what();
  }
  EXPECT_THROW(resolve_precision("fp16", with), std::invalid_argument);
  EXPECT_EQ(CpuFeatures::detect().avx512_bf16, bf16::available());
}

// A CPU with AMX tiles that this process cannot use runs vdpbf16ps, and the start line says why (the tiles
// would be the faster kernel): the OS without the tile state, or Linux refusing this process. A CPU without
// tiles, or with usable ones, has nothing to say.
TEST(NnPrecision, UnusableAmxTilesAreExplained) {
  using bf16::amx::Support;
  EXPECT_STREQ(bf16::amx::unusable_reason(Support::kUsable), "");
  EXPECT_STREQ(bf16::amx::unusable_reason(Support::kNoCpu), "");
  EXPECT_NE(std::string(bf16::amx::unusable_reason(Support::kNoOs)).find("Linux 5.16"), std::string::npos);
  EXPECT_NE(std::string(bf16::amx::unusable_reason(Support::kRefused)).find("ARCH_REQ_XCOMP_PERM"),
            std::string::npos);
  EXPECT_EQ(bf16::amx::hardware_available(), bf16::amx::support() == Support::kUsable);
  if (!bf16::available() || bf16::kernel() != bf16::Kernel::kAvx512Bf16) return;
  const std::string line = precision_description(Precision::kBf16);
  const std::string why = bf16::amx::unusable_reason(bf16::amx::support());
  EXPECT_EQ(line.find("unusable here") != std::string::npos, !why.empty()) << line;
  if (!why.empty()) {
    EXPECT_NE(line.find(why), std::string::npos) << line;
  }
}

}  // namespace
}  // namespace hns::nn
