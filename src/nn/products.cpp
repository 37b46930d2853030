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
  FloatBuffer shared_a;        // bf16: rows that several products multiply (convert_shared)
  FloatBuffer shared_at;       // bf16: x^T that several weight gradients multiply (convert_shared_t)
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

// A product y (+)= x M by matrix id of p in bf16: the shapes, and weights packed for the kernel in use.
void check_bf16_product(const Weights& p, int id, CMat x, Mat y) {
  const ProductMatrix& m = p.packed->info(id);
  HNS_NN_CHECK(m.rows == x.cols && m.cols == y.cols && x.rows == y.rows, "bf16 product of another shape");
  HNS_NN_CHECK(p.packed->kernel() == bf16::kernel(), "bf16 weights packed for another kernel");
}

// x in bf16, in the A layout of the kernel in use, into buf.
const bf16_t* convert_rows(CMat x, FloatBuffer& buf) {
  bf16_t* a = Scratch::take(buf, bf16::a_elems(x.rows, x.cols));
  bf16::convert_a(x.data, x.stride, x.rows, x.cols, a);
  return a;
}

// x in bf16 for a product y (+)= x M by matrix id of p (checked), in scratch.
const bf16_t* convert_x(const Weights& p, int id, CMat x, Mat y) {
  check_bf16_product(p, id, x, y);
  return convert_rows(x, scratch.a);
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

SharedRows convert_shared(const Weights& p, CMat x) {
  if (!p.bf16()) return x;
  HNS_NN_CHECK(p.packed->kernel() == bf16::kernel(), "bf16 weights packed for another kernel");
  return {x, convert_rows(x, scratch.shared_a), bf16::kernel()};
}

void matmul_bias(const Weights& p, int id, const float* w, const float* b, const SharedRows& x, Mat y) {
  const CMat& xm = x.mat;
  if (!p.bf16()) {
    for (int r = 0; r < y.rows; ++r) std::memcpy(y.row(r), b, sizeof(float) * y.cols);
    matmul_fp32(w, xm, y, true);
    return;
  }
  const bf16_t* a = x.converted;
  if (a == nullptr) {
    a = convert_x(p, id, xm, y);
  } else {  // convert_x's checks, and that the rows were converted for the kernel in use
    check_bf16_product(p, id, xm, y);
    HNS_NN_CHECK(x.kernel == bf16::kernel(), "bf16 rows converted for another kernel");
  }
  bf16::gemm_bias(a, xm.rows, xm.cols, p.packed->matrix(id), y.cols, b, y.data, y.stride);
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

// x^T in bf16, in gemm_at's layout for the kernel in use, into buf.
const bf16_t* convert_rows_t(CMat x, FloatBuffer& buf) {
  bf16_t* at = Scratch::take(buf, bf16::at_elems(x.cols, x.rows));
  bf16::convert_a_transposed(x.data, x.stride, x.rows, x.cols, at);
  return at;
}

// dw (+)= x^T dz in bf16 with dz already packed (b): A = x^T [x.cols, rows], the sum runs over the rows, in
// pairs. at: x^T already converted, or null (converted here, in scratch).
void matmul_grad_bf16(CMat x, const bf16_t* at, const bf16_t* b, int n, float* dw, bool accumulate) {
  if (at == nullptr) at = convert_rows_t(x, scratch.a);
  bf16::gemm_at(at, x.cols, x.rows, b, n, dw, n, accumulate);
}

const bf16_t* pack_dz(CMat dz) {
  bf16_t* b = Scratch::take(scratch.b, bf16::packed_elems(dz.rows, dz.cols));
  bf16::pack_b_rows(dz.data, dz.stride, dz.rows, dz.cols, b);
  return b;
}

}  // namespace

SharedRows convert_shared_t(const Weights& p, CMat x) {
  if (!p.bf16() || (p.stage != nullptr && GradStage::takes(x.rows))) return x;
  HNS_NN_CHECK(p.packed->kernel() == bf16::kernel(), "bf16 weights packed for another kernel");
  SharedRows shared(x);
  shared.converted_t = convert_rows_t(x, scratch.shared_at);
  shared.kernel = bf16::kernel();
  return shared;
}

void matmul_grad(const Weights& p, const SharedRows& x, CMat dz, float* dw, bool accumulate) {
  const CMat& xm = x.mat;
  if (!p.bf16()) return matmul_grad_fp32(xm, dz, dw, accumulate);
  HNS_NN_CHECK(xm.rows == dz.rows, "weight gradient of another row count");
  if (p.stage != nullptr && p.stage->add(xm, dz, dw, accumulate)) return;
  if (x.converted_t != nullptr)
    HNS_NN_CHECK(x.kernel == bf16::kernel(), "bf16 rows converted for another kernel");
  matmul_grad_bf16(xm, x.converted_t, pack_dz(dz), dz.cols, dw, accumulate);
}

void matmul_grad2(const Weights& p, CMat x0, float* dw0, CMat x1, float* dw1, CMat dz, bool accumulate) {
  HNS_NN_CHECK(x0.rows == dz.rows && x1.rows == dz.rows, "weight gradients of another row count");
  if (!p.bf16()) {
    matmul_grad_fp32(x0, dz, dw0, accumulate);
    return matmul_grad_fp32(x1, dz, dw1, accumulate);
  }
  if (p.stage != nullptr && p.stage->add2(x0, dw0, x1, dw1, dz, accumulate)) return;
  const bf16_t* b = pack_dz(dz);
  matmul_grad_bf16(x0, nullptr, b, dz.cols, dw0, accumulate);
  matmul_grad_bf16(x1, nullptr, b, dz.cols, dw1, accumulate);
}

// ---- GradStage

int GradStage::find(const float* dw) const {
  for (int i = 0; i < open_count(); ++i)
    if (blk(i).dw == dw) return i;
  return -1;
}

bool GradStage::shares_b(int i) const {
  return blk(i).b_from >= 0 || (i + 1 < open_count() && blk(i + 1).b_from == i);
}

void GradStage::flush_block(int i) {
  // A block and the one sharing its B go together (their pairs are the same rows).
  int first = i, last = i;
  if (blk(i).b_from >= 0) first = blk(i).b_from;
  if (first + 1 < open_count() && blk(first + 1).b_from == first) last = first + 1;
  for (int j = first; j <= last; ++j) {
    const Block& b = blk(j);
    const Block& owner = b.b_from >= 0 ? blk(b.b_from) : b;
    if (b.pairs > 0)
      bf16::gemm_at_pairs(reinterpret_cast<const bf16_t*>(b.at.data()), b.rows, b.pairs,
                          reinterpret_cast<const bf16_t*>(owner.b.data()), kPairs, b.n, b.dw, b.n);
  }
  for (int j = first; j <= last; ++j) blk(j).pairs = 0;
}

void GradStage::retire(int i) {
  flush_block(i);
  Block& b = blk(i);
  if (b.b_from >= 0) blk(b.b_from).dw = nullptr;
  if (i + 1 < open_count() && blk(i + 1).b_from == i) blk(i + 1).dw = nullptr;
  b.dw = nullptr;
}

GradStage::Block& GradStage::open(float* dw, int rows, int n, int b_from) {
  // A free block of this shape, or a new one: a block keeps its shape and buffers for good, so a stage
  // holds at most as many of a shape as a backward pass has gradients of it open at once.
  const bool own_b = b_from < 0;
  size_t slot = 0;
  while (slot < slots_.size() && (slots_[slot].busy || slots_[slot].rows != rows || slots_[slot].n != n ||
                                  slots_[slot].own_b != own_b))
    ++slot;
  if (slot == slots_.size()) {
    Block& fresh = slots_.emplace_back();
    fresh.rows = rows;
    fresh.n = n;
    fresh.own_b = own_b;
    fresh.at = FloatBuffer((bf16::at_pairs_elems(rows, kPairs) + 1) / 2);
    if (own_b) fresh.b = FloatBuffer((bf16::packed_pairs_elems(kPairs, n) + 1) / 2);
  }
  Block& b = slots_[slot];
  b.busy = true;
  b.dw = dw;
  b.pairs = 0;
  b.b_from = b_from;
  open_.push_back(int(slot));
  return b;
}

void GradStage::clear() {
  for (const int slot : open_) slots_[size_t(slot)].busy = false;
  open_.clear();
}

bool GradStage::takes(int rows) {
  return rows <= kMaxRows && bf16::kernel() == bf16::Kernel::kAvx512Bf16;
}

bool GradStage::stages(bool accumulate, int rows, std::initializer_list<const float*> dws) {
  if (accumulate && takes(rows)) return true;
  for (const float* dw : dws)
    if (const int i = find(dw); i >= 0) flush_block(i);
  return false;
}

bool GradStage::add(CMat x, CMat dz, float* dw, bool accumulate) {
  if (!stages(accumulate, x.rows, {dw})) return false;
  const int pairs = (x.rows + 1) / 2;
  int i = find(dw);
  if (i >= 0 && (shares_b(i) || blk(i).n != dz.cols || blk(i).rows != x.cols)) {
    retire(i);  // staged by add2 or with another shape: summed, and a block of its own from here
    i = -1;
  }
  if (i >= 0 && blk(i).pairs + pairs > kPairs) flush_block(i);
  Block& b = i >= 0 ? blk(i) : open(dw, x.cols, dz.cols, -1);
  bf16::convert_a_transposed_pairs(x.data, x.stride, x.rows, x.cols, kPairs, b.pairs,
                                   reinterpret_cast<bf16_t*>(b.at.data()));
  bf16::pack_b_rows_pairs(dz.data, dz.stride, dz.rows, dz.cols, kPairs, b.pairs,
                          reinterpret_cast<bf16_t*>(b.b.data()));
  b.pairs += pairs;
  return true;
}

bool GradStage::add2(CMat x0, float* dw0, CMat x1, float* dw1, CMat dz, bool accumulate) {
  if (!stages(accumulate, dz.rows, {dw0, dw1})) return false;
  const int pairs = (dz.rows + 1) / 2;
  int i0 = find(dw0);
  const int i1 = find(dw1);
  // The two blocks an earlier call opened for these inputs, or new ones.
  const bool same = i0 >= 0 && i1 == i0 + 1 && blk(i1).b_from == i0 && blk(i0).n == dz.cols &&
                    blk(i0).rows == x0.cols && blk(i1).rows == x1.cols;
  if (!same) {
    if (i0 >= 0) retire(i0);
    if (const int j = find(dw1); j >= 0) retire(j);
    i0 = open_count();
    open(dw0, x0.cols, dz.cols, -1);
    open(dw1, x1.cols, dz.cols, i0);
  } else if (blk(i0).pairs + pairs > kPairs) {
    flush_block(i0);
  }
  Block& b0 = blk(i0);
  Block& b1 = blk(i0 + 1);
  bf16::convert_a_transposed_pairs(x0.data, x0.stride, x0.rows, x0.cols, kPairs, b0.pairs,
                                   reinterpret_cast<bf16_t*>(b0.at.data()));
  bf16::convert_a_transposed_pairs(x1.data, x1.stride, x1.rows, x1.cols, kPairs, b1.pairs,
                                   reinterpret_cast<bf16_t*>(b1.at.data()));
  bf16::pack_b_rows_pairs(dz.data, dz.stride, dz.rows, dz.cols, kPairs, b0.pairs,
                          reinterpret_cast<bf16_t*>(b0.b.data()));
  b0.pairs += pairs;
  b1.pairs += pairs;
  return true;
}

void GradStage::flush() {
  for (int i = 0; i < open_count(); ++i)
    if (blk(i).b_from < 0) flush_block(i);
  clear();
}

size_t GradStage::max_bytes(const ParamLayout& layout) {
  size_t elems = 0;
  for (const ProductMatrix& m : layout.products())
    elems += 2 * size_t(kPairs) * (align_floats(size_t(m.rows)) + align_floats(size_t(m.cols)));
  return elems * sizeof(bf16_t);
}

}  // namespace hns::nn
