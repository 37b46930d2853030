#include "nn/products.hpp"

#include <oneapi/tbb/parallel_for.h>

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

void matmul(const Weights& p, int id, const float* w, CMat x, Mat y, bool accumulate) {
  if (!p.bf16()) {
    if (accumulate) {
      y.map().noalias() += x.map() * ConstWeights(w, x.cols, y.cols);
    } else {
      y.map().noalias() = x.map() * ConstWeights(w, x.cols, y.cols);
    }
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

void matmul_grad(const Weights& p, CMat x, CMat dz, float* dw, bool accumulate) {
  if (!p.bf16()) {
    if (accumulate) {
      WeightsMap(dw, x.cols, dz.cols).noalias() += x.map().transpose() * dz.map();
    } else {
      WeightsMap(dw, x.cols, dz.cols).noalias() = x.map().transpose() * dz.map();
    }
    return;
  }
  // A = x^T [x.cols, rows], B = dz [rows, dz.cols]: the sum runs over the rows, in pairs.
  bf16_t* a = Scratch::take(scratch.a, bf16::at_elems(x.cols, x.rows));
  bf16_t* b = Scratch::take(scratch.b, bf16::packed_elems(dz.rows, dz.cols));
  bf16::convert_a_transposed(x.data, x.stride, x.rows, x.cols, a);
  bf16::pack_b_rows(dz.data, dz.stride, dz.rows, dz.cols, b);
  bf16::gemm_at(a, x.cols, x.rows, b, dz.cols, dw, dz.cols, accumulate);
}

}  // namespace hns::nn
