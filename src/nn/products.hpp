// The layers' matrix products in either precision (nn/precision.hpp), and the packed bf16 weights they read.
//
// A layer registers each matrix it multiplies by in the ParamLayout (ParamLayout::add_product) and calls
// matmul / matmul_t / matmul_grad with the float matrix and that registration. With fp32 (Weights::packed
// null) these are the Eigen expressions the layers always used, bit for bit, with Eigen's packing buffers
// in per-thread scratch instead of the heap (products.cpp says why). With bf16 they run
// nn/bf16_gemm.hpp: the weights from PackedWeights (packed once per weight version by ActorCritic), the
// activations converted per call into per-thread scratch (which grows to the largest shape once and is then
// reused: no allocation in steady state).
#pragma once

#include "nn/bf16_gemm.hpp"
#include "nn/params.hpp"
#include "nn/tensor.hpp"

#include <vector>

namespace hns::nn {

// The bf16 forms of every product matrix of a layout: M as B (for x M) and, when packed for a backward
// pass, M^T as B (for dz M^T).
class PackedWeights {
 public:
  PackedWeights() = default;
  explicit PackedWeights(const ParamLayout& layout);

  // Packs every matrix from the float parameter values (and the transposes, with_transposed), in parallel
  // over matrices (each is packed by one thread: the result does not depend on the thread count), in the
  // layout of the bf16 kernel in use (bf16::kernel(); laid out anew if it changed since the last pack).
  void pack(const float* values, bool with_transposed);
  // The kernel whose layout the packed matrices have.
  bf16::Kernel kernel() const { return kernel_; }
  bool has_transposed() const { return has_transposed_; }
  // The registration of matrix id (its shape, for the products' checks).
  const ProductMatrix& info(int id) const {
    HNS_NN_CHECK(id >= 0 && size_t(id) < mats_.size(), "no such product matrix");
    return mats_[size_t(id)];
  }
  const bf16::bf16_t* matrix(int id) const { return data(offset_[size_t(id)]); }
  const bf16::bf16_t* transposed(int id) const { return data(offset_t_[size_t(id)]); }
  size_t bytes() const { return storage_.size() * sizeof(float); }

 private:
  const bf16::bf16_t* data(size_t elem) const {
    return reinterpret_cast<const bf16::bf16_t*>(storage_.data()) + elem;
  }
  void lay_out();  // offsets and storage for kernel_
  std::vector<ProductMatrix> mats_;
  bf16::Kernel kernel_ = bf16::Kernel::kAvx512Bf16;
  std::vector<size_t> offset_, offset_t_;  // bf16 elements into storage_, 64-byte aligned
  FloatBuffer storage_;                    // two bf16 per float
  bool has_transposed_ = false;
};

// The parameters as a forward or backward pass reads them: the float values and, for bf16 products, their
// packed forms (null: fp32 products). A plain float pointer converts to fp32 weights.
struct Weights {
  const float* values = nullptr;
  const PackedWeights* packed = nullptr;
  Weights(const float* v) : values(v) {}  // NOLINT(google-explicit-constructor): fp32 is the plain case
  Weights(const float* v, const PackedWeights* p) : values(v), packed(p) {}
  bool bf16() const { return packed != nullptr; }
};

// y (+)= x M for product matrix `id` of p, whose float form is w [x.cols, y.cols] (contiguous; it may be a
// reordered copy of the stored matrix, as the registration's col_map describes).
void matmul(const Weights& p, int id, const float* w, CMat x, Mat y, bool accumulate);
// y = b + x M, the bias b [y.cols] in every row: the same bits as y's rows set to b and matmul accumulating
// (fp32 and the AMX kernels do just that; the vdpbf16ps kernel starts its sums from b instead of that pass).
void matmul_bias(const Weights& p, int id, const float* w, const float* b, CMat x, Mat y);
// dx (+)= dz M^T, the same matrix: w [dx.cols, dz.cols].
void matmul_t(const Weights& p, int id, const float* w, CMat dz, Mat dx, bool accumulate);
// dw (+)= x^T dz: dw [x.cols, dz.cols] contiguous (a weight gradient, summed over the rows).
void matmul_grad(const Weights& p, CMat x, CMat dz, float* dw, bool accumulate);
// The same for two inputs that share dz (the LSTM's input and recurrent weights): dw0 (+)= x0^T dz and
// dw1 (+)= x1^T dz, with the same bits as two matmul_grad calls; bf16 converts dz once.
void matmul_grad2(const Weights& p, CMat x0, float* dw0, CMat x1, float* dw1, CMat dz, bool accumulate);

}  // namespace hns::nn
