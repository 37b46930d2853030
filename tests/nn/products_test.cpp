// The layers' float products (nn/products.hpp with fp32 weights): the same bits as the Eigen expressions
// they stand for, and no memory taken per call once a thread has met its largest shape. The bf16 weight
// gradients staged over several chunks, and rows converted once for several products: the same bits as one
// product per chunk, and as converting per product.
#include <gtest/gtest.h>
#include <malloc.h>
#include <sys/resource.h>

#include <Eigen/Core>
#include <algorithm>
#include <cstring>
#include <vector>

#include "nn/bf16_gemm.hpp"
#include "nn/params.hpp"
#include "nn/products.hpp"
#include "test_util.hpp"

namespace hns::nn {
namespace {

using RowMat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using Map = Eigen::Map<const RowMat>;

// Puts back the bf16 kernel in use when the test ends, however it ends.
struct KernelRestorer {
  bf16::Kernel saved = bf16::kernel();
  ~KernelRestorer() { bf16::set_kernel(saved); }
};

// body(kernel, weights) under each bf16 kernel this CPU runs (AMX's exact arithmetic emulated where it has no
// AMX), with the layout's matrices packed for it; the kernel in use is put back afterwards.
template <class Body>
void for_each_bf16_kernel(const ParamLayout& layout, const std::vector<float>& values, Body&& body) {
  const KernelRestorer restore;
  std::vector<bf16::Kernel> kernels = {bf16::Kernel::kAvx512Bf16, bf16::Kernel::kAmxEmulated};
  if (bf16::amx_available()) kernels.push_back(bf16::Kernel::kAmx);
  for (const bf16::Kernel kern : kernels) {
    SCOPED_TRACE(bf16::kernel_name(kern));
    bf16::set_kernel(kern);
    PackedWeights packed(layout);
    packed.pack(values.data(), false);
    body(kern, Weights(values.data(), &packed));
  }
}

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

struct Shape {
  int rows, in, out;
};
// Rows, inputs, outputs: below Eigen's coefficient-wise threshold and at it (3 + 8 + 9 = 20 for matmul_t and
// matmul_grad), one row (matmul_t's matrix-vector path; matmul pads it to 8) or one output (matrix-vector),
// the networks' shapes (an odd 281, a 1,120-deep attention input), and ones deep or wide enough for several
// of Eigen's depth and column blocks.
const Shape kShapes[] = {{3, 5, 7},      {3, 8, 9},       {1, 64, 128},    {120, 128, 1},    {17, 33, 9},
                         {160, 64, 281}, {64, 1120, 128}, {256, 160, 512}, {1024, 1536, 96}, {40, 3000, 700}};

// Every operand at a row stride wider than its columns, as the layers' views into wider tensors are. matmul
// pads the rows after its last whole 8-row panel with zero rows (products.cpp says why): its reference is
// the expression over x padded so.
TEST(NnProducts, FloatProductsEqualTheirEigenExpressionsBitForBit) {
  for (const Shape& s : kShapes) {
    SCOPED_TRACE(::testing::Message() << s.rows << " x " << s.in << " x " << s.out);
    const int xs = s.in + 3, ys = s.out + 5;  // row strides
    const std::vector<float> w = testing::random_vector(size_t(s.in) * s.out, 1);
    const std::vector<float> x = testing::random_vector(size_t(s.rows) * xs, 2);
    const std::vector<float> dz = testing::random_vector(size_t(s.rows) * ys, 3);
    const std::vector<float> start_y = testing::random_vector(size_t(s.rows) * ys, 4);
    const std::vector<float> start_dx = testing::random_vector(size_t(s.rows) * xs, 5);
    const std::vector<float> start_dw = testing::random_vector(size_t(s.in) * s.out, 6);
    const CMat xv(x.data(), s.rows, s.in, xs), dzv(dz.data(), s.rows, s.out, ys);
    for (const bool acc : {false, true}) {
      std::vector<float> y = start_y;
      matmul(Weights(w.data()), 0, w.data(), xv, Mat(y.data(), s.rows, s.out, ys), acc);
      const int padded = (s.rows + 7) / 8 * 8;
      std::vector<float> x_pad(size_t(padded) * xs, 0.0f), y_ref(size_t(padded) * ys, 0.0f);
      std::copy(x.begin(), x.end(), x_pad.begin());
      std::copy(start_y.begin(), start_y.end(), y_ref.begin());
      auto yr = Mat(y_ref.data(), padded, s.out, ys).map();
      if (acc) {
        yr.noalias() += CMat(x_pad.data(), padded, s.in, xs).map() * Map(w.data(), s.in, s.out);
      } else {
        yr.noalias() = CMat(x_pad.data(), padded, s.in, xs).map() * Map(w.data(), s.in, s.out);
      }
      y_ref.resize(y.size());
      EXPECT_TRUE(same_bits(y, y_ref)) << "matmul, accumulate " << acc;

      std::vector<float> dx = start_dx, dx_ref = start_dx;
      matmul_t(Weights(w.data()), 0, w.data(), dzv, Mat(dx.data(), s.rows, s.in, xs), acc);
      auto dr = Mat(dx_ref.data(), s.rows, s.in, xs).map();
      if (acc) {
        dr.noalias() += dzv.map() * Map(w.data(), s.in, s.out).transpose();
      } else {
        dr.noalias() = dzv.map() * Map(w.data(), s.in, s.out).transpose();
      }
      EXPECT_TRUE(same_bits(dx, dx_ref)) << "matmul_t, accumulate " << acc;

      std::vector<float> dw = start_dw, dw_ref = start_dw;
      matmul_grad(Weights(w.data()), xv, dzv, dw.data(), acc);
      auto gr = Eigen::Map<RowMat>(dw_ref.data(), s.in, s.out);
      if (acc) {
        gr.noalias() += xv.map().transpose() * dzv.map();
      } else {
        gr.noalias() = xv.map().transpose() * dzv.map();
      }
      EXPECT_TRUE(same_bits(dw, dw_ref)) << "matmul_grad, accumulate " << acc;
    }
  }
}

// A GradStage (bf16, vdpbf16ps kernel) sums several chunks' weight gradients in one product each: the same
// bits as one product per chunk, whatever comes between. Eleven "chunks" of products as a backward pass
// makes them: a dense layer's (rows around a chunk's 40, odd ones padded with a zero pair), the LSTM's two
// inputs sharing dz (matmul_grad2), and an entity layer whose rows vary from a few to more than a stage takes
// (those run at once, after what was staged for that gradient); now and then a product that overwrites a
// staged gradient, and each of the LSTM's inputs alone. Enough rows to fill the stage's blocks several times.
TEST(NnProducts, StagedWeightGradientsEqualOneProductPerChunkBitForBit) {
  if (!bf16::available()) GTEST_SKIP() << "this CPU has no AVX512-BF16";
  const KernelRestorer restore;
  bf16::set_kernel(bf16::Kernel::kAvx512Bf16);
  const PackedWeights packed{ParamLayout{}};
  const Weights direct(nullptr, &packed);
  GradStage stage;
  Weights staged(nullptr, &packed);
  staged.stage = &stage;

  const int dense_rows[] = {40, 40, 39, 40, 17, 40, 1, 40, 40, 33, 40};
  const int entity_rows[] = {12, 90, 7, 200, 3, 64, 81, 80, 2, 150, 5};
  struct Grad {
    int in, out;
    std::vector<float> dw;
  };
  // dense [281, 64], LSTM input and recurrent [37, 128] and [20, 128], entity [15, 40]
  std::vector<Grad> want = {{281, 64, {}}, {37, 128, {}}, {20, 128, {}}, {15, 40, {}}};
  for (size_t i = 0; i < want.size(); ++i)
    want[i].dw = testing::random_vector(size_t(want[i].in) * want[i].out, uint32_t(10 + i));
  std::vector<Grad> got = want;
  bool staged_before_flush = false;
  for (int c = 0; c < 11; ++c) {
    SCOPED_TRACE(::testing::Message() << "chunk " << c);
    auto run = [&](const Weights& p, std::vector<Grad>& g) {
      const int r = dense_rows[c], e = entity_rows[c];
      const uint32_t seed = uint32_t(100 * c);
      const std::vector<float> x = testing::random_vector(size_t(r) * 290, seed + 1);
      const std::vector<float> dz = testing::random_vector(size_t(r) * 130, seed + 2);
      const std::vector<float> xe = testing::random_vector(size_t(e) * 15, seed + 3);
      const std::vector<float> dze = testing::random_vector(size_t(e) * 40, seed + 4);
      // (row strides wider than the columns, as the layers' views are)
      matmul_grad(p, CMat(x.data(), r, 281, 290), CMat(dz.data(), r, 64, 130), g[0].dw.data(), c % 4 != 3);
      if (c == 5) {
        matmul_grad(p, CMat(x.data(), r, 37, 290), CMat(dz.data(), r, 128, 130), g[1].dw.data(), true);
      } else if (c == 8) {  // the second input alone: the block that sums with the first one's dz
        matmul_grad(p, CMat(x.data() + 200, r, 20, 290), CMat(dz.data(), r, 128, 130), g[2].dw.data(), true);
      } else {
        matmul_grad2(p, CMat(x.data() + 100, r, 37, 290), g[1].dw.data(), CMat(x.data() + 200, r, 20, 290),
                     g[2].dw.data(), CMat(dz.data(), r, 128, 130), true);
      }
      matmul_grad(p, CMat(xe.data(), e, 15), CMat(dze.data(), e, 40), g[3].dw.data(), true);
    };
    run(direct, want);
    run(staged, got);
    for (size_t i = 0; i < got.size(); ++i) staged_before_flush |= !same_bits(got[i].dw, want[i].dw);
  }
  EXPECT_TRUE(staged_before_flush) << "nothing was left in the stage: the test no longer tests it";
  stage.flush();
  EXPECT_TRUE(stage.empty());
  for (size_t i = 0; i < got.size(); ++i) EXPECT_TRUE(same_bits(got[i].dw, want[i].dw)) << "gradient " << i;
}

// Rows converted once for several products (convert_shared: the embeddings' main rows, the attention's
// projections' input) give each product the bits of converting them itself, also with other products in
// between (which reuse the per-thread scratch of the per-call conversions), with both bf16 kernels' layouts
// (AMX's emulated; the tiles where the CPU has them); fp32 weights convert nothing, and rows converted for
// one kernel are refused by another.
TEST(NnProducts, RowsConvertedOnceGiveTheBitsOfConvertingPerProduct) {
  ParamLayout layout;
  const size_t w0 = layout.add_kernel_xavier("w0", 281, 64, 281.0f, 64.0f);
  const size_t w1 = layout.add_kernel_xavier("w1", 281, 40, 281.0f, 40.0f);
  const size_t w2 = layout.add_kernel_xavier("w2", 33, 64, 33.0f, 64.0f);
  const int id0 = layout.add_product({w0, 281, 64, {}});
  const int id1 = layout.add_product({w1, 281, 40, {}});
  const int id2 = layout.add_product({w2, 33, 64, {}});
  const std::vector<float> values = testing::random_vector(layout.buffer_floats(), 5);
  const std::vector<float> bias = testing::random_vector(64, 6);
  const std::vector<float> x = testing::random_vector(size_t(40) * 290, 7);
  const std::vector<float> other = testing::random_vector(size_t(40) * 33, 8);
  const CMat rows(x.data(), 40, 281, 290);
  EXPECT_EQ(convert_shared(Weights(values.data()), rows).converted, nullptr);
  if (!bf16::available()) GTEST_SKIP() << "this CPU has no AVX512-BF16";
  for_each_bf16_kernel(layout, values, [&](bf16::Kernel kern, const Weights& p) {
    auto run = [&](const SharedRows& in, std::vector<float>& y0, std::vector<float>& y1,
                   std::vector<float>& y2) {
      y0.assign(size_t(40) * 64, 0.0f);
      y1.assign(size_t(40) * 40, 0.0f);
      y2.assign(size_t(40) * 64, 0.0f);
      matmul_bias(p, id0, values.data() + w0, bias.data(), in, Mat(y0.data(), 40, 64));
      matmul(p, id2, values.data() + w2, CMat(other.data(), 40, 33), Mat(y2.data(), 40, 64), false);
      matmul_bias(p, id1, values.data() + w1, bias.data(), in, Mat(y1.data(), 40, 40));
    };
    std::vector<float> want0, want1, want2, got0, got1, got2;
    run(rows, want0, want1, want2);
    const SharedRows shared = convert_shared(p, rows);
    EXPECT_NE(shared.converted, nullptr);
    run(shared, got0, got1, got2);
    EXPECT_TRUE(same_bits(got0, want0));
    EXPECT_TRUE(same_bits(got1, want1));
    EXPECT_TRUE(same_bits(got2, want2));
    // The same rows under another kernel's layout: refused, not misread.
    const SharedRows other_kernel(
        rows, shared.converted,
        kern == bf16::Kernel::kAvx512Bf16 ? bf16::Kernel::kAmxEmulated : bf16::Kernel::kAvx512Bf16);
    EXPECT_THROW(matmul_bias(p, id0, values.data() + w0, bias.data(), other_kernel, Mat(got0.data(), 40, 64)),
                 std::logic_error);
  });
}

// x^T converted once (convert_shared_t) gives every weight gradient the bits of converting x in each, with a
// product, a gradient and a row conversion of other rows in between (which use the other scratch buffers).
// Rows converted for another kernel are refused; fp32 weights and rows that a stage takes are not converted.
TEST(NnProducts, TransposedRowsConvertedOnceGiveTheBitsOfConvertingPerGradient) {
  ParamLayout layout;
  const size_t w0 = layout.add_kernel_xavier("w0", 64, 48, 64.0f, 48.0f);
  const int id0 = layout.add_product({w0, 64, 48, {}});
  const std::vector<float> values = testing::random_vector(layout.buffer_floats(), 15);
  const int rows = 203;  // more than a stage takes, odd
  const std::vector<float> x = testing::random_vector(size_t(rows) * 70, 16);
  const std::vector<float> dz0 = testing::random_vector(size_t(rows) * 48, 17);
  const std::vector<float> dz1 = testing::random_vector(size_t(rows) * 96, 18);
  const std::vector<float> other = testing::random_vector(size_t(rows) * 64, 19);
  const CMat xm(x.data(), rows, 64, 70);
  EXPECT_EQ(convert_shared_t(Weights(values.data()), xm).converted_t, nullptr);
  if (!bf16::available()) GTEST_SKIP() << "this CPU has no AVX512-BF16";
  for_each_bf16_kernel(layout, values, [&](bf16::Kernel kern, const Weights& p) {
    auto run = [&](const SharedRows& in, std::vector<float>& g0, std::vector<float>& g1) {
      g0 = testing::random_vector(size_t(64) * 48, 20);
      g1.assign(size_t(64) * 96, 0.0f);
      std::vector<float> y(size_t(rows) * 48), g_other(size_t(64) * 48, 0.0f);
      matmul_grad(p, in, CMat(dz0.data(), rows, 48), g0.data(), true);
      matmul(p, id0, values.data() + w0, CMat(other.data(), rows, 64), Mat(y.data(), rows, 48), false);
      matmul_grad(p, CMat(other.data(), rows, 64), CMat(dz0.data(), rows, 48), g_other.data(), false);
      (void)convert_shared(p, CMat(other.data(), rows, 64));
      matmul_grad(p, in, CMat(dz1.data(), rows, 96), g1.data(), false);
    };
    std::vector<float> want0, want1, got0, got1;
    run(xm, want0, want1);
    const SharedRows shared = convert_shared_t(p, xm);
    ASSERT_NE(shared.converted_t, nullptr);
    run(shared, got0, got1);
    EXPECT_TRUE(same_bits(got0, want0));
    EXPECT_TRUE(same_bits(got1, want1));
    // The same rows under another kernel's layout: refused, not misread.
    SharedRows other_kernel = shared;
    other_kernel.kernel =
        kern == bf16::Kernel::kAvx512Bf16 ? bf16::Kernel::kAmxEmulated : bf16::Kernel::kAvx512Bf16;
    EXPECT_THROW(matmul_grad(p, other_kernel, CMat(dz0.data(), rows, 48), got0.data(), true),
                 std::logic_error);
    // With a stage, as in training: a gradient of few rows is staged first, then one of these rows, which the
    // stage does not take, goes to the same gradient. What the stage holds for it is summed first, then the
    // shared form's product: the order of converting per gradient.
    auto staged_run = [&](const SharedRows& in, std::vector<float>& g) {
      GradStage st;
      Weights w = p;
      w.stage = &st;
      g = testing::random_vector(size_t(64) * 48, 21);
      matmul_grad(w, CMat(other.data(), 40, 64), CMat(dz0.data(), 40, 48), g.data(), true);
      matmul_grad(w, in, CMat(dz0.data(), rows, 48), g.data(), true);
      st.flush();
    };
    std::vector<float> want_staged, got_staged;
    staged_run(xm, want_staged);
    staged_run(convert_shared_t(p, xm), got_staged);
    EXPECT_TRUE(same_bits(got_staged, want_staged));
    // A stage that takes gradients of these rows converts them itself: nothing converted here.
    GradStage stage;
    Weights staged = p;
    staged.stage = &stage;
    const CMat few(x.data(), GradStage::kMaxRows, 64, 70);
    EXPECT_EQ(convert_shared_t(staged, few).converted_t == nullptr, GradStage::takes(GradStage::kMaxRows));
    EXPECT_NE(convert_shared_t(staged, xm).converted_t, nullptr);
  });
}

long minor_faults_of_this_thread() {
  rusage u{};
  getrusage(RUSAGE_THREAD, &u);
  return u.ru_minflt;
}

// A training iteration runs thousands of products; memory taken and given back per product costs a page
// fault per 4 KB touched (Eigen's packing buffers, freed at every product's end, cost a one-thread `paper`
// run about 30 % of its time that way: nn/README.md). Here the C library is made to return every block of
// 128 KB or more to the system at once (an explicit mmap threshold also stops glibc from raising it as a
// program runs; under AddressSanitizer, whose allocator ignores the call, large blocks are mapped and
// unmapped anyway): a product that took its buffers from the heap would fault on them at every call, some
// 7,500 times here. A few faults are allowed for what a loaded host does to any thread's pages.
TEST(NnProducts, FloatProductsTouchNoNewMemoryOnceWarm) {
  mallopt(M_MMAP_THRESHOLD, 128 * 1024);
  const Shape shapes[] = {{2560, 256, 1024}, {1120, 128, 256}, {160, 1024, 256}, {600, 1024, 1024}};
  struct Data {
    std::vector<float> w, x, y, dw;
  };
  std::vector<Data> data;
  for (const Shape& s : shapes)
    data.push_back(
        {testing::random_vector(size_t(s.in) * s.out, 1), testing::random_vector(size_t(s.rows) * s.in, 2),
         testing::random_vector(size_t(s.rows) * s.out, 3), std::vector<float>(size_t(s.in) * s.out)});
  auto run_all = [&] {
    for (size_t i = 0; i < data.size(); ++i) {
      const Shape& s = shapes[i];
      Data& d = data[i];
      const CMat x(d.x.data(), s.rows, s.in), y(d.y.data(), s.rows, s.out);
      matmul(Weights(d.w.data()), 0, d.w.data(), x, Mat(d.y.data(), s.rows, s.out), false);
      matmul_t(Weights(d.w.data()), 0, d.w.data(), y, Mat(d.x.data(), s.rows, s.in), false);
      matmul_grad(Weights(d.w.data()), x, y, d.dw.data(), false);
    }
  };
  run_all();  // the thread's scratch grows to the largest shape here
  const long before = minor_faults_of_this_thread();
  for (int rep = 0; rep < 3; ++rep) run_all();
  EXPECT_LT(minor_faults_of_this_thread() - before, 50);
}

}  // namespace
}  // namespace hns::nn
