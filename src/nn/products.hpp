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

#include <initializer_list>
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

// Weight gradients of several training chunks summed by one bf16 product each (nn/README.md "Weight
// gradients over several chunks"). A chunk of `small` has 40 rows, and a product x^T dz that sums only 40
// rows into a weight gradient runs well below the kernel's speed (each tile of C is loaded, summed over a
// few pairs and stored again); four chunks' rows in one product run near it. A backward pass whose Weights
// carry a stage hands it each accumulating x^T dz of at most kMaxRows rows: x^T and dz are converted into
// the stage's blocks (bf16::convert_a_transposed_pairs, pack_b_rows_pairs), and the products into the
// gradients run at flush(), or when a block would overflow. Per gradient the chunks' pairs stay in their
// order, so the sums are those of one product per chunk, bit for bit. With the vdpbf16ps kernel only (the
// AMX kernels' tiles pad k to 16 pairs per product: add() declines, after summing what it holds for the
// gradient with the vdpbf16ps arithmetic it was staged for). One stage serves one network's backward passes
// of one gradient group, one at a time; distinct gradients must not overlap.
class GradStage {
 public:
  static constexpr int kPairs = 80;    // pairs of rows a block holds (160 rows: four chunks of `small`)
  static constexpr int kMaxRows = 80;  // products of more rows run at once
  // Stages dw += x^T dz (accumulate: dw already holds a sum) and returns true, or returns false where the
  // caller runs the product itself (more rows than kMaxRows, a product that overwrites dw, not the vdpbf16ps
  // kernel), after flushing whatever this stage holds for dw.
  bool add(CMat x, CMat dz, float* dw, bool accumulate);
  // The same for two inputs sharing dz (matmul_grad2): dz converted once.
  bool add2(CMat x0, float* dw0, CMat x1, float* dw1, CMat dz, bool accumulate);
  // Every staged product, each into its gradient.
  void flush();
  bool empty() const { return open_.empty(); }
  // True where add would stage a weight gradient of this many rows that accumulates.
  static bool takes(int rows);
  // Drops whatever is staged: a group's workspace may come back with rows still staged when an exception in
  // another group cancelled its last chunk's tasks (and so its flush).
  void clear();
  // Bytes a stage may hold for the backward passes of a layout's networks: at most one block per product
  // matrix. (A block keeps its shape and is reused for it; a gradient takes one block as long as it is
  // always staged by the same call, add or add2, with one shape, as the networks' layers do. One staged
  // otherwise retires its block and takes another until the next flush.)
  static size_t max_bytes(const ParamLayout& layout);

 private:
  struct Block {
    int rows = 0;         // the gradient's rows: x's columns
    int n = 0;            // its columns: dz's columns
    bool own_b = true;    // false: the block sums with another's B (add2's second input)
    FloatBuffer at, b;    // bf16: x^T (kPairs pairs) and dz (kPairs pairs per panel; own_b only)
    bool busy = false;    // open
    float* dw = nullptr;  // while open: the gradient (null: retired, summed)
    int pairs = 0;        // staged since the block's last product
    int b_from = -1;      // the open block whose B it sums with, or -1: its own
  };
  int open_count() const { return static_cast<int>(open_.size()); }
  Block& blk(int i) { return slots_[size_t(open_[size_t(i)])]; }
  const Block& blk(int i) const { return slots_[size_t(open_[size_t(i)])]; }
  int find(const float* dw) const;
  bool shares_b(int i) const;
  // Sums open block i (and the block sharing its B) into its gradient; the blocks stay open, empty.
  void flush_block(int i);
  // flush_block, and the block (and its partner) no longer stands for its gradient.
  void retire(int i);
  Block& open(float* dw, int rows, int n, int b_from);
  // True where a product of these rows is staged; else flushes what is staged for dws.
  bool stages(bool accumulate, int rows, std::initializer_list<const float*> dws);
  std::vector<Block> slots_;  // every block so far, each of one shape for good
  std::vector<int> open_;     // the open ones, in the order they were opened since the last flush
};

// The parameters as a forward or backward pass reads them: the float values and, for bf16 products, their
// packed forms (null: fp32 products). A plain float pointer converts to fp32 weights. A backward pass with a
// stage hands its weight gradients to it (bf16 only; the caller flushes the stage before reading them).
struct Weights {
  const float* values = nullptr;
  const PackedWeights* packed = nullptr;
  GradStage* stage = nullptr;
  Weights(const float* v) : values(v) {}  // NOLINT(google-explicit-constructor): fp32 is the plain case
  Weights(const float* v, const PackedWeights* p) : values(v), packed(p) {}
  bool bf16() const { return packed != nullptr; }
};

// y (+)= x M for product matrix `id` of p, whose float form is w [x.cols, y.cols] (contiguous; it may be a
// reordered copy of the stored matrix, as the registration's col_map describes).
void matmul(const Weights& p, int id, const float* w, CMat x, Mat y, bool accumulate);
// Rows that several products multiply, with their bf16 form converted once by convert_shared: the entity
// embeddings' x_self parts (and the self embedding) all multiply the same main rows, the attention's q/k and
// v projections their common input. A plain CMat or Mat converts to rows without one (each bf16 product
// converts them itself). The bf16 form lives in the converting thread's scratch: only that thread may use
// it, until its next convert_shared, while the rows stay as they were and the bf16 kernel stays the one it
// was converted for (`kernel`, checked by each product). The transposed form of convert_shared_t (for weight
// gradients) lives in a scratch buffer of its own, with the same rules up to the thread's next
// convert_shared_t.
struct SharedRows {
  SharedRows(CMat rows) : mat(rows) {}  // NOLINT(google-explicit-constructor): the plain case
  SharedRows(Mat rows) : mat(rows) {}   // NOLINT(google-explicit-constructor): the same
  SharedRows(CMat rows, const bf16::bf16_t* bf16_rows, bf16::Kernel for_kernel)
      : mat(rows), converted(bf16_rows), kernel(for_kernel) {}
  CMat mat;
  const bf16::bf16_t* converted = nullptr;    // the rows as the A of x M (convert_shared)
  const bf16::bf16_t* converted_t = nullptr;  // x^T as the A of x^T dz (convert_shared_t)
  bf16::Kernel kernel = bf16::Kernel::kAvx512Bf16;
};
// x in bf16 once, in this thread's scratch for shared rows (fp32 weights: nothing converted).
SharedRows convert_shared(const Weights& p, CMat x);
// x^T in bf16 once, for the weight gradients x^T dz of several products of the same input rows (the
// attention's q/k and v projections, the embeddings' x_self parts), in this thread's scratch for shared
// transposed rows, with the same rules of use as convert_shared's. Nothing is converted for fp32 weights, nor
// where p's stage takes weight gradients of this many rows (it converts them into its blocks).
SharedRows convert_shared_t(const Weights& p, CMat x);
// y = b + x M, the bias b [y.cols] in every row: the same bits as y's rows set to b and matmul accumulating
// (fp32 and the AMX kernels do just that; the vdpbf16ps kernel starts its sums from b instead of that pass).
// x's bf16 form, where it has one, is used as it is: the same bits as converting x here.
void matmul_bias(const Weights& p, int id, const float* w, const float* b, const SharedRows& x, Mat y);
// dx (+)= dz M^T, the same matrix: w [dx.cols, dz.cols].
void matmul_t(const Weights& p, int id, const float* w, CMat dz, Mat dx, bool accumulate);
// dw (+)= x^T dz: dw [x.cols, dz.cols] contiguous (a weight gradient, summed over the rows). x's transposed
// bf16 form, where it has one, is used as it is: the same bits as converting x here.
void matmul_grad(const Weights& p, const SharedRows& x, CMat dz, float* dw, bool accumulate);
// The same for two inputs that share dz (the LSTM's input and recurrent weights): dw0 (+)= x0^T dz and
// dw1 (+)= x1^T dz, with the same bits as two matmul_grad calls; bf16 converts dz once.
void matmul_grad2(const Weights& p, CMat x0, float* dw0, CMat x1, float* dw1, CMat dz, bool accumulate);

}  // namespace hns::nn
