#include "nn/products.hpp"

#include <oneapi/tbb/parallel_for.h>

#include <algorithm>

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

// Per-thread bf16 scratch for the activations of one product (A, and B for a weight gradient).
struct Scratch {
  FloatBuffer a, b;
  FloatBuffer panel;  // fp32: a padded panel of the rows after the last whole one, x then y
  static bf16_t* take(FloatBuffer& buf, size_t elems) {
    const size_t floats = (elems + 1) / 2;
    if (buf.size() < floats) buf.resize(floats);
    return reinterpret_cast<bf16_t*>(buf.data());
  }
};
thread_local Scratch scratch;

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
  if (whole > 0) {
    Mat top(y.data, whole, y.cols, y.stride);
    if (accumulate) {
      top.map().noalias() += CMat(x.data, whole, x.cols, x.stride).map() * wm;
    } else {
      top.map().noalias() = CMat(x.data, whole, x.cols, x.stride).map() * wm;
    }
  }
  const int rest = x.rows - whole;
  if (rest == 0) return;
  const size_t xs = static_cast<size_t>(kRowPanel) * x.cols, ys = static_cast<size_t>(kRowPanel) * y.cols;
  if (scratch.panel.size() < xs + ys) scratch.panel.resize(xs + ys);
  float* xp = scratch.panel.data();
  float* yp = xp + xs;
  std::fill(xp, xp + xs, 0.0f);
  for (int r = 0; r < rest; ++r) std::copy_n(x.row(whole + r), x.cols, xp + static_cast<size_t>(r) * x.cols);
  Mat panel(yp, kRowPanel, y.cols, y.cols);
  if (accumulate) {
    std::fill(yp, yp + ys, 0.0f);
    for (int r = 0; r < rest; ++r)
      std::copy_n(y.row(whole + r), y.cols, yp + static_cast<size_t>(r) * y.cols);
    panel.map().noalias() += CMat(xp, kRowPanel, x.cols, x.cols).map() * wm;
  } else {
    panel.map().noalias() = CMat(xp, kRowPanel, x.cols, x.cols).map() * wm;
  }
  for (int r = 0; r < rest; ++r) std::copy_n(yp + static_cast<size_t>(r) * y.cols, y.cols, y.row(whole + r));
}

}  // namespace

void matmul(const Weights& p, int id, const float* w, CMat x, Mat y, bool accumulate) {
  if (!p.bf16()) {
    matmul_fp32(w, x, y, accumulate);
    return;
  }
  const ProductMatrix& m = p.packed->info(id);
  HNS_NN_CHECK(m.rows == x.cols && m.cols == y.cols && x.rows == y.rows, "bf16 product of another shape");
  HNS_NN_CHECK(p.packed->kernel() == bf16::kernel(), "bf16 weights packed for another kernel");
  bf16_t* a = Scratch::take(scratch.a, bf16::a_elems(x.rows, x.cols));
  bf16::convert_a(x.data, x.stride, x.rows, x.cols, a);
  bf16::gemm(a, x.rows, x.cols, p.packed->matrix(id), y.cols, y.data, y.stride, accumulate);
}

void matmul_t(const Weights& p, int id, const float* w, CMat dz, Mat dx, bool accumulate) {
  if (!p.bf16()) {
    if (accumulate) {
      dx.map().noalias() += dz.map() * ConstWeights(w, dx.cols, dz.cols).transpose();
    } else {
      dx.map().noalias() = dz.map() * ConstWeights(w, dx.cols, dz.cols).transpose();
    }
    return;
  }
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
  if (accumulate) {
    WeightsMap(dw, x.cols, dz.cols).noalias() += x.map().transpose() * dz.map();
  } else {
    WeightsMap(dw, x.cols, dz.cols).noalias() = x.map().transpose() * dz.map();
  }
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
