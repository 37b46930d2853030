#include "nn/products.hpp"

#include <oneapi/tbb/parallel_for.h>

#include <algorithm>
#include <cstring>
#include <type_traits>

namespace hns::nn {
namespace {

using RowMat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using ConstWeights = Eigen::Map<const RowMat>;
using WeightsMap = Eigen::Map<RowMat>;
using bf16::bf16_t;

constexpr size_t kAlignElems = kAlignBytes / sizeof(bf16_t);

size_t align_elems(size_t n) {
  return (n + kAlignElems - 1) / kAlignElems * kAlignElems;
}

// Per-thread scratch: bf16 activations of one product (A, and B for a weight gradient), and the fp32
// products' buffers.
struct Scratch {
  FloatBuffer a, b;
  FloatBuffer panel;           // fp32: a padded panel of the rows after the last whole one, x then y
  FloatBuffer pack_a, pack_b;  // fp32: Eigen's packed blocks of its two operands
  static float* take_floats(FloatBuffer& buf, size_t floats) {
    if (buf.size() < floats) buf.resize(floats);
    return buf.data();
  }
  static bf16_t* take(FloatBuffer& buf, size_t elems) {
    return reinterpret_cast<bf16_t*>(take_floats(buf, (elems + 1) / 2));
  }
};
thread_local Scratch scratch;

// ---- fp32: Eigen's GEMM without its allocation
//
// Eigen 3.4 (GeneralMatrixMatrix.h) packs blocks of both operands into two buffers that it takes at every
// product's start and gives back at its end: from the stack up to 128 KB, from the heap beyond. The C
// library returns large freed blocks to the system, so the next product meets fresh pages and faults on
// every 4 KB of them: at one thread, fp32 `paper` training ran 1.43x faster without them (nn/README.md).
// product() below is `dst.noalias() (+)= lhs * rhs` as Eigen evaluates it, with the same kernels, blocking
// and order of sums (so the same bits), but with the two buffers in this thread's scratch, which grows to the
// largest product once. It rests on Eigen 3.4's internals, as matmul_fp32's row panels do; the products' test
// compares it with the expressions bit for bit.
#if !EIGEN_VERSION_AT_LEAST(3, 4, 0) || EIGEN_VERSION_AT_LEAST(3, 5, 0)
#error "products.cpp follows Eigen 3.4's GEMM internals: check them against this Eigen's"
#endif
#if defined(EIGEN_HAS_OPENMP) || defined(EIGEN_USE_BLAS)
#error \
    "products.cpp follows Eigen's sequential, built-in GEMM: build without OpenMP and without EIGEN_USE_BLAS"
#endif
namespace ei = Eigen::internal;
using Index = Eigen::Index;

// Eigen's blocking of a float product into a row-major destination (gemm_blocking_space<RowMajor, float,
// float, Dynamic, Dynamic, Dynamic, 1, false> constructed as generic_product_impl constructs it: the same
// sizes), its buffers in the scratch. Eigen computes a row-major product transposed: its rows are the
// destination's columns.
class ScratchBlocking : public ei::level3_blocking<float, float> {
 public:
  ScratchBlocking(Index rows, Index cols, Index depth) {
    m_mc = cols;
    m_nc = rows;
    m_kc = depth;
    ei::computeProductBlockingSizes<float, float, 1, Index>(m_kc, m_mc, m_nc, 1);
    m_blockA = Scratch::take_floats(scratch.pack_a, static_cast<size_t>(m_mc * m_kc));
    m_blockB = Scratch::take_floats(scratch.pack_b, static_cast<size_t>(m_kc * m_nc));
  }
};

template <class X>
constexpr int storage_order() {
  return (std::remove_cvref_t<X>::Flags & Eigen::RowMajorBit) != 0 ? Eigen::RowMajor : Eigen::ColMajor;
}

// dst (+)= lhs rhs for plain float maps (or their transposes) and a row-major dst with unit inner stride.
template <class Dst, class Lhs, class Rhs>
void product(Dst&& dst, const Lhs& lhs, const Rhs& rhs, bool accumulate) {
  const Index rows = dst.rows(), cols = dst.cols(), depth = lhs.cols();
  // Where Eigen would not run its GEMM (coefficient by coefficient below its size threshold, matrix times
  // vector for one row or column, nothing for an empty product), the expression, which allocates nothing.
  if (rows + cols + depth < EIGEN_GEMM_TO_COEFFBASED_THRESHOLD || rows <= 1 || cols <= 1 || depth == 0) {
    if (accumulate) {
      dst.noalias() += lhs * rhs;
    } else {
      dst.noalias() = lhs * rhs;
    }
    return;
  }
  static_assert(storage_order<Dst>() == Eigen::RowMajor &&
                std::remove_cvref_t<Dst>::InnerStrideAtCompileTime == 1);
  const auto& l = ei::blas_traits<Lhs>::extract(lhs);
  const auto& r = ei::blas_traits<Rhs>::extract(rhs);
  if (!accumulate) dst.setZero();  // (as Eigen's evalTo: zeros, then the products added)
  ScratchBlocking blocking(rows, cols, depth);
  ei::general_matrix_matrix_product<Index, float, storage_order<decltype(l)>(), false, float,
                                    storage_order<decltype(r)>(), false, Eigen::RowMajor,
                                    1>::run(rows, cols, depth, l.data(), l.outerStride(), r.data(),
                                            r.outerStride(), dst.data(), 1, dst.outerStride(), 1.0f,
                                            blocking);
}

}  // namespace

PackedWeights::PackedWeights(const ParamLayout& layout) : mats_(layout.products()) {
  HNS_NN_CHECK(bf16::available(), "bf16 weights on a CPU without AVX512-BF16");
  lay_out();
}

void PackedWeights::lay_out() {
  kernel_ = bf16::kernel();
  offset_.clear();
  offset_t_.clear();
  size_t end = 0;
  for (const ProductMatrix& m : mats_) {
    offset_.push_back(end);
    end += align_elems(bf16::packed_elems(m.rows, m.cols));
  }
  for (const ProductMatrix& m : mats_) {
    offset_t_.push_back(end);
    end += align_elems(bf16::packed_elems(m.cols, m.rows));
  }
  storage_.resize((end + 1) / 2);
}

void PackedWeights::pack(const float* values, bool with_transposed) {
  if (kernel_ != bf16::kernel()) lay_out();
  const int n = static_cast<int>(mats_.size());
  tbb::parallel_for(0, with_transposed ? 2 * n : n, [&](int i) {
    const ProductMatrix& m = mats_[size_t(i % n)];
    const float* w = values + m.offset;
    const int* map = m.col_map.empty() ? nullptr : m.col_map.data();
    bf16_t* out = reinterpret_cast<bf16_t*>(storage_.data());
    if (i < n) {
      bf16::pack_b(w, m.cols, m.rows, m.cols, false, map, out + offset_[size_t(i)]);
    } else {
      // M^T [cols, rows] (the map reorders the stored columns, which are M^T's rows).
      bf16::pack_b(w, m.cols, m.cols, m.rows, true, map, out + offset_t_[size_t(i - n)]);
    }
  });
  has_transposed_ = with_transposed;
}

namespace {

// y (+)= x W in fp32 with each row's result independent of how many rows the product has. Eigen computes the
// rows beyond the last whole 4-row panel by another kernel whose sums round differently, so a row's bits
// would depend on its position in the product (an inference chunk of 16 rows against a training chunk of
// 150, say, and the rollout's log-probabilities would not be those the update recomputes). Whole panels of
// kRowPanel rows go to Eigen; the rest is padded with zero rows in a scratch panel. (This rests on
// Eigen 3.4's kernels: a row-major product is computed transposed, rows becoming 4-wide column panels;
// products small enough for Eigen's coefficient-wise path, rows + cols + depth < 20, would round differently
// again, and no layer of the networks is that small. NnNetworkPrecision.ChunkOfTenStepsEqualsTenActSteps
// checks it.)
constexpr int kRowPanel = 8;

void matmul_fp32(const float* w, CMat x, Mat y, bool accumulate) {
  const ConstWeights wm(w, x.cols, y.cols);
  const int whole = x.rows / kRowPanel * kRowPanel;
  if (whole > 0)
    product(Mat(y.data, whole, y.cols, y.stride).map(), CMat(x.data, whole, x.cols, x.stride).map(), wm,
            accumulate);
  const int rest = x.rows - whole;
  if (rest == 0) return;
  const size_t xs = static_cast<size_t>(kRowPanel) * x.cols, ys = static_cast<size_t>(kRowPanel) * y.cols;
  if (scratch.panel.size() < xs + ys) scratch.panel.resize(xs + ys);
  float* xp = scratch.panel.data();
  float* yp = xp + xs;
  std::fill(xp, xp + xs, 0.0f);
  for (int r = 0; r < rest; ++r) std::copy_n(x.row(whole + r), x.cols, xp + static_cast<size_t>(r) * x.cols);
  if (accumulate) {
    std::fill(yp, yp + ys, 0.0f);
    for (int r = 0; r < rest; ++r)
      std::copy_n(y.row(whole + r), y.cols, yp + static_cast<size_t>(r) * y.cols);
  }
  product(Mat(yp, kRowPanel, y.cols, y.cols).map(), CMat(xp, kRowPanel, x.cols, x.cols).map(), wm,
          accumulate);
  for (int r = 0; r < rest; ++r) std::copy_n(yp + static_cast<size_t>(r) * y.cols, y.cols, y.row(whole + r));
}

}  // namespace

namespace {

// x in bf16 for a product y (+)= x M by matrix id of p (checked against the shapes), in scratch.
const bf16_t* convert_x(const Weights& p, int id, CMat x, Mat y) {
  const ProductMatrix& m = p.packed->info(id);
  HNS_NN_CHECK(m.rows == x.cols && m.cols == y.cols && x.rows == y.rows, "bf16 product of another shape");
  HNS_NN_CHECK(p.packed->kernel() == bf16::kernel(), "bf16 weights packed for another kernel");
  bf16_t* a = Scratch::take(scratch.a, bf16::a_elems(x.rows, x.cols));
  bf16::convert_a(x.data, x.stride, x.rows, x.cols, a);
  return a;
}

}  // namespace

void matmul(const Weights& p, int id, const float* w, CMat x, Mat y, bool accumulate) {
  if (!p.bf16()) {
    matmul_fp32(w, x, y, accumulate);
    return;
  }
  const bf16_t* a = convert_x(p, id, x, y);
  bf16::gemm(a, x.rows, x.cols, p.packed->matrix(id), y.cols, y.data, y.stride, accumulate);
}

void matmul_bias(const Weights& p, int id, const float* w, const float* b, CMat x, Mat y) {
  if (!p.bf16()) {
    for (int r = 0; r < y.rows; ++r) std::memcpy(y.row(r), b, sizeof(float) * y.cols);
    matmul_fp32(w, x, y, true);
    return;
  }
  const bf16_t* a = convert_x(p, id, x, y);
  bf16::gemm_bias(a, x.rows, x.cols, p.packed->matrix(id), y.cols, b, y.data, y.stride);
}

void matmul_t(const Weights& p, int id, const float* w, CMat dz, Mat dx, bool accumulate) {
  if (!p.bf16())
    return product(dx.map(), dz.map(), ConstWeights(w, dx.cols, dz.cols).transpose(), accumulate);
  HNS_NN_CHECK(p.packed->has_transposed(), "bf16 backward without transposed weights packed");
  const ProductMatrix& m = p.packed->info(id);
  HNS_NN_CHECK(m.rows == dx.cols && m.cols == dz.cols && dz.rows == dx.rows, "bf16 product of another shape");
  HNS_NN_CHECK(p.packed->kernel() == bf16::kernel(), "bf16 weights packed for another kernel");
  bf16_t* a = Scratch::take(scratch.a, bf16::a_elems(dz.rows, dz.cols));
  bf16::convert_a(dz.data, dz.stride, dz.rows, dz.cols, a);
  bf16::gemm(a, dz.rows, dz.cols, p.packed->transposed(id), dx.cols, dx.data, dx.stride, accumulate);
}

namespace {

void matmul_grad_fp32(CMat x, CMat dz, float* dw, bool accumulate) {
  product(WeightsMap(dw, x.cols, dz.cols), x.map().transpose(), dz.map(), accumulate);
}

// dw (+)= x^T dz in bf16 with dz already packed (b): A = x^T [x.cols, rows], the sum runs over the rows, in
// pairs.
void matmul_grad_bf16(CMat x, const bf16_t* b, int n, float* dw, bool accumulate) {
  bf16_t* a = Scratch::take(scratch.a, bf16::at_elems(x.cols, x.rows));
  bf16::convert_a_transposed(x.data, x.stride, x.rows, x.cols, a);
  bf16::gemm_at(a, x.cols, x.rows, b, n, dw, n, accumulate);
}

const bf16_t* pack_dz(CMat dz) {
  bf16_t* b = Scratch::take(scratch.b, bf16::packed_elems(dz.rows, dz.cols));
  bf16::pack_b_rows(dz.data, dz.stride, dz.rows, dz.cols, b);
  return b;
}

}  // namespace

void matmul_grad(const Weights& p, CMat x, CMat dz, float* dw, bool accumulate) {
  if (!p.bf16()) return matmul_grad_fp32(x, dz, dw, accumulate);
  matmul_grad_bf16(x, pack_dz(dz), dz.cols, dw, accumulate);
}

void matmul_grad2(const Weights& p, CMat x0, float* dw0, CMat x1, float* dw1, CMat dz, bool accumulate) {
  HNS_NN_CHECK(x0.rows == dz.rows && x1.rows == dz.rows, "weight gradients of another row count");
  if (!p.bf16()) {
    matmul_grad_fp32(x0, dz, dw0, accumulate);
    return matmul_grad_fp32(x1, dz, dw1, accumulate);
  }
  const bf16_t* b = pack_dz(dz);
  matmul_grad_bf16(x0, b, dz.cols, dw0, accumulate);
  matmul_grad_bf16(x1, b, dz.cols, dw1, accumulate);
}

}  // namespace hns::nn
