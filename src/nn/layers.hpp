// Layers with forward and backward passes over batches of rows ([rows, features]) and of entity sets
// ([rows, entities, features], stored as [rows * entities, features]). docs/game.md §10.2 gives the
// semantics.
//
// Conventions shared by every layer:
// - A layer keeps only sizes and offsets into the flat parameter buffer (nn/params.hpp). forward() takes the
//   parameter base pointer; backward() takes it and the gradient base pointer, and *accumulates* into the
//   gradients (so a caller can sum several chunks into one buffer in a fixed order).
// - Kernels are stored [in, out] row-major (TensorFlow's layout): y = x W + b. Matrix products go through
//   nn/products.hpp (Eigen's GEMM in fp32, nn/bf16_gemm.hpp in bf16).
// - All activations live in caller-owned memory (views, or a layer's Buffers bound from an Arena once per
//   batch shape); nothing here allocates (the products' packing buffers are per-thread scratch that grows
//   to the largest shape once).
// - backward() may overwrite its incoming gradient (dy) with the pre-activation gradient.
#pragma once

#include "nn/kernels.hpp"
#include "nn/params.hpp"
#include "nn/products.hpp"
#include "nn/tensor.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace hns::nn {

// How a dense kernel is initialised: Xavier uniform (fans = in, out), N(0, std), or normc(std).
struct KernelInit {
  Init kind = Init::kXavierUniform;
  float std = 0.0f;
};

// y = act(x W + b): x [rows, in], W [in, out], b [out], y [rows, out].
class Dense {
 public:
  Dense() = default;
  // Registers "<name>/w" and "<name>/b", and W as a product matrix unless a caller multiplies by W in
  // another form itself (register_product false: forward and backward must not be called in bf16).
  Dense(ParamLayout& layout, const std::string& name, int in, int out, Activation act, KernelInit init = {},
        bool register_product = true);

  int in() const { return in_; }
  int out() const { return out_; }
  size_t w_offset() const { return w_; }
  size_t b_offset() const { return b_; }
  // 2 * rows * in * out.
  double flops(int rows) const { return 2.0 * rows * in_ * out_; }

  // x: rows, or rows with their bf16 form (convert_shared).
  void forward(const Weights& params, const SharedRows& x, Mat y) const;
  // z = x W without bias or activation (for fused epilogues).
  void forward_linear(const Weights& params, CMat x, Mat z) const;
  // dy: gradient w.r.t. y, overwritten with the pre-activation gradient (using y for the ReLU mask).
  // Accumulates dW, db; writes dx (or adds to it if accumulate_dx); dx may be empty (not needed). x's
  // transposed bf16 form, where it has one (convert_shared_t), serves dW.
  void backward(const Weights& params, float* grads, const SharedRows& x, CMat y, Mat dy, Mat dx,
                bool accumulate_dx) const;
  // The same from the pre-activation gradient dz.
  void backward_preact(const Weights& params, float* grads, const SharedRows& x, CMat dz, Mat dx,
                       bool accumulate_dx) const;

 private:
  int in_ = 0;
  int out_ = 0;
  Activation act_ = Activation::kNone;
  size_t w_ = 0;  // [in, out]
  size_t b_ = 0;  // [out]
  int id_ = -1;   // W's product registration (-1: none)
};

// Layer norm over the features of each row, learned gain (init 1) and bias (init 0), eps 1e-12, optionally
// preceded by a bias + activation (the epilogue of a Dense whose linear part ran through forward_linear).
class LayerNorm {
 public:
  LayerNorm() = default;
  // Registers "<name>/gain" and "<name>/bias".
  LayerNorm(ParamLayout& layout, const std::string& name, int n);

  int n() const { return n_; }
  // y = LN(x); stats [rows, 2] receives (mean, rstd) per row.
  void forward(const Weights& params, CMat x, Mat y, float* stats) const;
  // a = act(z + pre_bias) (written to a, which may be z), y = LN(a).
  void forward_fused(const Weights& params, CMat z, const float* pre_bias, Activation act, Mat a, Mat y,
                     float* stats) const;
  // dy is read; dx written (may alias dy). Accumulates dgain, dbias.
  void backward(const Weights& params, float* grads, CMat x, const float* stats, CMat dy, Mat dx) const;
  // The same two with one side's rows scattered or gathered (the attention's compact rows to and from the
  // entities' rows): forward writes x's row r to y's row y_rows[r] (y's other rows untouched); backward reads
  // dy's row dy_rows[r] for x's row r and writes dx's row r. The arithmetic of each row is that of the above.
  void forward_scatter(const Weights& params, CMat x, const int32_t* y_rows, Mat y, float* stats) const;
  void backward_gather(const Weights& params, float* grads, CMat x, const float* stats,
                       const int32_t* dy_rows, CMat dy, Mat dx) const;
  // Backward of forward_fused: dz = d/dz (activation mask applied); accumulates dgain, dbias, and
  // pre_bias_grad (if not null) += colsum(dz).
  void backward_fused(const Weights& params, float* grads, CMat a, const float* stats, Activation act,
                      CMat dy, Mat dz, float* pre_bias_grad) const;

 private:
  int n_ = 0;
  size_t gain_ = 0;
  size_t bias_ = 0;
};

// Circular 1-D convolution over `length` positions with `in_ch` channels (x [rows, length * in_ch], position
// major), `out_ch` filters of width `kernel`, circular padding kernel / 2 on each side, ReLU;
// y [rows, length * out_ch] (position major, i.e. TF's flatten of [length, out_ch]). Kernel [kernel, in_ch,
// out_ch] stored as [kernel * in_ch, out_ch], Xavier (fan_in = kernel * in_ch, fan_out = kernel * out_ch).
class CircConv1d {
 public:
  CircConv1d() = default;
  CircConv1d(ParamLayout& layout, const std::string& name, int length, int in_ch, int out_ch, int kernel);

  int in_width() const { return length_ * in_ch_; }
  int out_width() const { return length_ * out_ch_; }
  double flops(int rows) const { return 2.0 * rows * length_ * out_ch_ * kernel_ * in_ch_; }

  void forward(const Weights& params, CMat x, Mat y) const;
  // dy overwritten with the pre-activation gradient; accumulates dW, db; no input gradient (lidar is an
  // input).
  void backward(const Weights& params, float* grads, CMat x, CMat y, Mat dy) const;

 private:
  int length_ = 0;
  int in_ch_ = 0;
  int out_ch_ = 0;
  int kernel_ = 0;
  size_t w_ = 0;
  size_t b_ = 0;
  // The output-order passes (AVX-512 builds, one input channel, the extended input and the weights in two
  // vectors each, the bias in one): per 16-output vector of a row's [length, out_ch] output, 32 ints: the
  // 16 lanes' positions p, then their filters f. Empty where the passes do not apply.
  std::vector<int32_t> lane_pf_;
};

// Where one entity type sits in an entity tensor X [rows, entities, width]: slots [first, first + count).
struct EntitySlots {
  float* data = nullptr;  // X
  int rows = 0;
  int entities = 0;  // entities per row in X
  int width = 0;     // features per entity in X
  int first = 0;
  int count = 0;
  // [rows, width] view of slot `first + e`.
  Mat slot(int e) const {
    return {data + static_cast<ptrdiff_t>(first + e) * width, rows, width, entities * width};
  }
  float* at(int r, int e) const { return data + (static_cast<ptrdiff_t>(r) * entities + first + e) * width; }
};

// Embedding of one entity type with x_self concatenated to every entity (docs/game.md §10.2 concat with
// broadcast): X[r, e] = relu([main[r], ent[r, e]] W + b), W [main_width + features, width] (Xavier), b
// [width]. Computed as main W_main (once per row) + ent W_ent (per entity), which equals the concatenated
// product.
class EntityEmbedding {
 public:
  EntityEmbedding() = default;
  EntityEmbedding(ParamLayout& layout, const std::string& name, int main_width, int features, int width);

  int features() const { return features_; }
  // rows agent-steps with `entities` entities of this type in all (rows x count, or only the unmasked ones).
  double flops(int rows, double entities) const {
    return 2.0 * rows * main_width_ * width_ + 2.0 * entities * features_ * width_;
  }

  // main [rows, main_width] (with its bf16 form where the caller converted it once for every embedding:
  // convert_shared); ent [rows * count, features]; scratch [rows, width]. Writes out's slots.
  void forward(const Weights& params, const SharedRows& main, CMat ent, const EntitySlots& out,
               Mat scratch) const;
  // dout: gradient w.r.t. X (same slots, read only); out: the forward's X (ReLU mask).
  // scratch_rows [rows, width], scratch_ent [rows * count, width]. Accumulates dW, db; adds to d_main. main's
  // transposed bf16 form, where the caller converted it once for every embedding (convert_shared_t), serves
  // dW.
  void backward(const Weights& params, float* grads, const SharedRows& main, CMat ent, const EntitySlots& out,
                const EntitySlots& dout, Mat scratch_rows, Mat scratch_ent, Mat d_main) const;

 private:
  int main_width_ = 0;
  int features_ = 0;
  int width_ = 0;
  size_t w_ = 0;  // [main_width + features, width]: rows [0, main_width) multiply main
  size_t b_ = 0;
  int main_id_ = 0;  // product registrations of W's main rows and its entity rows
  int ent_id_ = 0;
};

// Masked residual multi-head self-attention block (docs/game.md §10.2 residual_sa_block, n_mlp = 1):
//   xn = LN_pre(x) (optional); qk = xn Wqk + bqk (stored interleaved, as the original: q = [..., 0],
//   k = [..., 1] of [E, heads, dh, 2]); v = xn Wv + bv; p = masked_softmax(q k^T / sqrt(dh)) over keys;
//   att = concat_h(p v); res = x + att Wo + bo; out = LN_post(res) (optional).
// x, out: [rows * E, width]; mask [rows, E] (0/1 per entity, shared by all queries).
// A masked entity is neither a key nor a query: the network pools over unmasked entities only, so a masked
// query's output is never used. Its work is skipped entirely: the unmasked entities of all rows are
// gathered into compact rows first (every product and norm runs on those), a masked entity's output is 0
// and it gets no gradient. Wqk's columns are permuted once per call to [q of every head, k of every head], so
// a head's queries and keys are contiguous slices of the product's rows (no de-interleaving copy).
// Keys of one row padded to a whole number of vectors (the attention computes a query's scores against all
// keys at once).
inline int attention_key_stride(int entities) {
  return (entities + kernels::simd_width() - 1) / kernels::simd_width() * kernels::simd_width();
}

class SelfAttention {
 public:
  // The compact row count is padded to a multiple of this with zero rows: Eigen's GEMM runs a row count
  // that is not a multiple of its 4-column panels through another kernel, whose sums round differently,
  // and a row's result must not depend on how many entities the other rows see (the rollout's one-step
  // inference and the training chunks must agree to the bit).
  static constexpr int kCompactRowAlign = 8;
  // Activations kept for backward, and backward scratch, for `rows` rows of E entities. The per-entity
  // buffers hold the compact rows (n_live <= rows * E of them, in row and then entity order).
  struct Buffers {
    int rows = 0, entities = 0, width = 0, heads = 0;
    int live_count = 0;         // n_live of the last forward
    int32_t* live = nullptr;    // [rows * E] entity row (r * E + e) of each compact row
    int32_t* offset = nullptr;  // [rows + 1] compact rows of row r: [offset[r], offset[r + 1])
    float* ones = nullptr;      // [E] all 1: the softmax mask of compact rows
    float* xc = nullptr;        // [rows * E, width] x gathered
    float* xn = nullptr;        // [rows * E, width] LN_pre output (or unused if no pre LN)
    float* ln_pre = nullptr;    // [rows * E, 2] stats
    float* w_qk = nullptr;      // [width + 1, 2 * width] Wqk then bqk, columns permuted to [q heads, k heads]
    float* dw_qk = nullptr;     // [width + 1, 2 * width] their gradient, permuted (backward scratch)
    float* qk = nullptr;        // [rows * E, 2 * width] row: q of heads 0.., then k of heads 0..
    float* v = nullptr;         // [rows * E, width]
    float* probs = nullptr;     // [rows, heads, E, E]
    float* att = nullptr;       // [rows * E, width] heads concatenated
    float* res = nullptr;       // [rows * E, width] residual sum (before LN_post)
    float* out_c = nullptr;     // [rows * E, width] LN_post output, compact
    float* ln_post = nullptr;   // [rows * E, 2]
    float* d_xn = nullptr;      // [rows * E, width]
    float* d_qk = nullptr;      // [rows * E, 2 * width] permuted as qk
    float* d_v = nullptr;       // [rows * E, width]
    float* d_att = nullptr;     // [rows * E, width]
    float* d_res = nullptr;     // [rows * E, width]
    float* d_p = nullptr;       // [E, E]
    float* kt = nullptr;        // [dh, attention_key_stride(E)] one head's keys (or values) transposed
    float* scores = nullptr;    // [E, attention_key_stride(E)] one head's scores, query by query
    // The bf16 scores' operands: bf16::attention_scratch_elems(E, dh) elements.
    bf16::bf16_t* scratch16 = nullptr;
    Buffers() = default;
    Buffers(int rows, int entities, int width, int heads)
        : rows(rows), entities(entities), width(width), heads(heads) {}
    void bind(Arena& arena);
  };

  SelfAttention() = default;
  // Registers "<name>/ln_pre", "<name>/qk", "<name>/v", "<name>/mlp1", "<name>/ln_post".
  SelfAttention(ParamLayout& layout, const std::string& name, int width, int heads, bool pre_ln,
                bool post_ln);

  int width() const { return width_; }
  int heads() const { return heads_; }
  // `entity_rows` entities in all, `pairs` (query, key) pairs in all (sum over rows of entities squared).
  double flops(double entity_rows, double pairs) const;

  void forward(const Weights& params, CMat x, const float* mask, int entities, Buffers& bufs, Mat out) const;
  // dout [rows * E, width] read; dx written (gradient w.r.t. x, residual path included).
  void backward(const Weights& params, float* grads, CMat x, const float* mask, int entities, Buffers& bufs,
                CMat out, CMat dout, Mat dx) const;

 private:
  int width_ = 0;
  int heads_ = 0;
  bool pre_ln_ = true;
  bool post_ln_ = true;
  LayerNorm ln_pre_;
  Dense qk_;
  int qk_id_ = 0;  // Wqk with its columns in the permuted order
  Dense v_;
  Dense mlp1_;
  LayerNorm ln_post_;
};

// Masked average pooling over entities (docs/game.md §10.2 entity_pooling):
// out[r] = sum_e x[r, e] * mask[r, e] / (sum_e mask[r, e] + 1e-5). x [rows * E, width]; out [rows, width].
// Entities with mask 0 are skipped entirely (their features never enter the result).
inline constexpr float kPoolEps = 1e-5f;
void masked_mean_pool(CMat x, const float* mask, int entities, Mat out);
// dx[r, e] = mask[r, e] / (sum mask + 1e-5) * dout[r] (written, zero for masked entities).
void masked_mean_pool_backward(CMat dout, const float* mask, int entities, Mat dx);

// BasicLSTMCell (docs/game.md §10.2) over sequences: rows are ordered sequence-major, row = b * steps + t,
// for `sequences` sequences of `steps` steps. W [in + units, 4 units] (Xavier; rows [0, in) multiply x, the
// rest h), b [4 units] (zeros); gate order i, j, f, o; forget bias 1. The state (c, h) is carried across
// steps, zeroed before any step whose reset flag is set, and backprop runs through the whole chunk of steps.
// State tensors are [sequences, 2 * units]: c in [0, units), h in [units, 2 units).
class Lstm {
 public:
  // W_h packed for the forward's recurrent product (w_h) and W_h^T for the backward's (w_h_t).
  struct Packed {
    float* w_h = nullptr;
    float* w_h_t = nullptr;
  };
  struct Buffers {
    int sequences = 0, steps = 0, in = 0, units = 0;
    float* gates = nullptr;    // [rows, 4 units]: x W_x + b, then + h W_h, then activated in place
    float* c = nullptr;        // [rows, units]
    float* tanh_c = nullptr;   // [rows, units]
    float* h = nullptr;        // [rows, units] the layer's output
    float* c_prev = nullptr;   // [rows, units] state entering each step (after reset)
    float* h_prev = nullptr;   // [rows, units]
    float* d_gates = nullptr;  // [rows, 4 units]
    Packed packed;             // [4 units * units] each: W_h (and W_h^T) packed by this call, if not given
    float* dh = nullptr;       // [sequences, units] carried gradient
    float* dc = nullptr;       // [sequences, units]
    Buffers() = default;
    Buffers(int sequences, int steps, int in, int units)
        : sequences(sequences), steps(steps), in(in), units(units) {}
    void bind(Arena& arena);
  };

  Lstm() = default;
  // Registers "<name>/w" and "<name>/b".
  Lstm(ParamLayout& layout, const std::string& name, int in, int units);

  int in() const { return in_; }
  int units() const { return units_; }
  double flops(int rows) const { return 2.0 * rows * (in_ + units_) * 4.0 * units_; }

  // x [sequences * steps, in]; reset [rows] (null: never); state_in [sequences, 2 units] (null: zeros);
  // state_out [sequences, 2 units] (null: not written). `sequences` may be below bufs.sequences. Output:
  // bufs.h.
  // The recurrent products (a few rows per step) read W_h packed by pack(); `packed` is that of the
  // current params (shared by many calls: the weights do not change within a minibatch), or null to pack
  // into bufs on this call.
  void forward(const Weights& params, CMat x, int sequences, int steps, const float* reset,
               const float* state_in, Buffers& bufs, float* state_out, const Packed* packed = nullptr) const;
  // dh [rows, units] gradient w.r.t. the outputs; dx [rows, in] written. The initial state gets no gradient.
  void backward(const Weights& params, float* grads, CMat x, int sequences, int steps, const float* reset,
                Buffers& bufs, CMat dh, Mat dx, const Packed* packed = nullptr) const;
  // W_h (and, for backward, W_h^T) packed for kernels::gemm_acc_packed, packed_floats() each.
  size_t packed_floats() const { return kernels::gemm_packed_floats(units_, 4 * units_); }
  void pack(const float* params, bool for_backward, Packed& out) const;

 private:
  int in_ = 0;
  int units_ = 0;
  size_t w_ = 0;
  size_t b_ = 0;
  int wx_id_ = 0;  // product registrations of W_x and W_h
  int wh_id_ = 0;
};

}  // namespace hns::nn
