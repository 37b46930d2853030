// Fused SIMD kernels of the network (xsimd), each with a scalar reference path (`*_scalar`) that gives
// bit-identical results: both are instantiations of one template (see nn/simd.hpp). Kernels work on one row
// (n features, contiguous) or on rows x n, never allocate, and accept any n >= 0 (vector loop + scalar tail).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace hns::nn {

enum class Activation : uint8_t { kNone, kRelu };

// Observation normalisation constants (docs/game.md §10.2).
inline constexpr float kObsClip = 5.0f;
// Layer norm epsilon (tf.contrib.layers.layer_norm).
inline constexpr float kLayerNormEps = 1e-12f;
// Masked softmax: logits of masked keys are lowered by this, and the sum gets this added (docs/game.md
// §10.2).
inline constexpr float kMaskedLogitPenalty = 1e10f;
inline constexpr float kSoftmaxSumEps = 1e-10f;
// BasicLSTMCell forget bias.
inline constexpr float kLstmForgetBias = 1.0f;

namespace kernels {

// Floats per vector register in this build.
int simd_width();

// The instruction set of this build (CMake's HNS_ISA) and what it gives the kernels, e.g.
// "avx512 (AVX-512, 16 floats per vector, FMA)".
std::string isa_description();
// Empty when this CPU has every instruction set extension the build was compiled for; otherwise a sentence
// naming the first one it lacks. (A program linking this library never gets that far on such a CPU: a
// start-up check, compiled for baseline x86-64, prints the same and exits with status 2 before main.)
std::string isa_unsupported();

// Observation normalisation fused with masking, over rows x n (contiguous):
// y[r, f] = clip((x[r, f] - mean[f]) * inv_std[f], -kObsClip, kObsClip) if row_mask[r] != 0, else 0.
// row_mask may be null (no masking). y may alias x.
void normalize_obs(const float* x, const float* mean, const float* inv_std, const float* row_mask, int rows,
                   int n, float* y);
void normalize_obs_scalar(const float* x, const float* mean, const float* inv_std, const float* row_mask,
                          int rows, int n, float* y);

// y[f] = act(y[f] + bias[f]) over one row of n; bias may be null.
void bias_act(float* y, const float* bias, Activation act, int n);
void bias_act_scalar(float* y, const float* bias, Activation act, int n);

// Masked softmax of one row of n logits (docs/game.md §10.2): l = logits * scale - (1 - mask) * 1e10;
// l -= max(l); e = exp(l) * mask; p = e / (sum(e) + 1e-10) * mask. mask values are 0 or 1. p may alias
// logits.
void masked_softmax(const float* logits, const float* mask, float scale, int n, float* p);
void masked_softmax_scalar(const float* logits, const float* mask, float scale, int n, float* p);
// Its backward for 0/1 masks: dlogits = scale * p * (dp - sum(p * dp)). dlogits may alias dp.
void masked_softmax_backward(const float* p, const float* dp, float scale, int n, float* dlogits);
void masked_softmax_backward_scalar(const float* p, const float* dp, float scale, int n, float* dlogits);

// Activation + layer norm of one row: a = act(z + pre_bias) (pre_bias may be null; a may alias z; without
// pre_bias and activation a is not written and may be null), then
// y = (a - mean(a)) / sqrt(var(a) + 1e-12) * gain + bias. stats receives {mean, 1 / sqrt(var + eps)}.
void act_layer_norm(const float* z, const float* pre_bias, Activation act, const float* gain,
                    const float* bias, int n, float* a, float* y, float* stats);
void act_layer_norm_scalar(const float* z, const float* pre_bias, Activation act, const float* gain,
                           const float* bias, int n, float* a, float* y, float* stats);
// Its backward: from a, stats and dy, accumulates dgain += dy * xhat and dbias += dy, and writes dz (the
// gradient w.r.t. z; the activation's mask applied). dz may alias dy.
void act_layer_norm_backward(const float* a, const float* stats, const float* gain, const float* dy,
                             Activation act, int n, float* dgain, float* dbias, float* dz);
void act_layer_norm_backward_scalar(const float* a, const float* stats, const float* gain, const float* dy,
                                    Activation act, int n, float* dgain, float* dbias, float* dz);
// The forward pass for a block of count <= kNormRows rows (row r at z[r], a[r], y[r]; stats [count, 2]; a[r]
// null where the single-row form allows a null a, or equal to z[r]; a y row must not be another row's z or
// a), with the bits of count single-row calls: the rows' sums are reduced together (the serial sum of a
// row's lanes is what limits the single-row form on short rows). AVX-512 builds only; elsewhere it runs row
// by row. Throws std::logic_error for more than kNormRows rows.
inline constexpr int kNormRows = 16;
void act_layer_norm_rows(int count, const float* const* z, const float* pre_bias, Activation act,
                         const float* gain, const float* bias, int n, float* const* a, float* const* y,
                         float* stats);

// LSTM cell nonlinearities for one row of u units (BasicLSTMCell, gate order i, j, f, o). g holds the 4u
// pre-activations; gates receives sigmoid(i), tanh(j), sigmoid(f + 1), sigmoid(o) (may alias g);
// c = c_prev * f + i * j; tanh_c = tanh(c); h = tanh_c * o.
void lstm_cell(const float* g, const float* c_prev, int u, float* gates, float* c, float* tanh_c, float* h);
void lstm_cell_scalar(const float* g, const float* c_prev, int u, float* gates, float* c, float* tanh_c,
                      float* h);
// Its backward: dh is the gradient w.r.t. h, dc (may be null = 0) w.r.t. c from the next step; writes dg
// (gradient w.r.t. the 4u pre-activations) and dc_prev (may alias dc).
void lstm_cell_backward(const float* gates, const float* c_prev, const float* tanh_c, const float* dh,
                        const float* dc, int u, float* dg, float* dc_prev);
void lstm_cell_backward_scalar(const float* gates, const float* c_prev, const float* tanh_c, const float* dh,
                               const float* dc, int u, float* dg, float* dc_prev);

// Products of few rows against a weight matrix used many times (the LSTM's recurrent step: one row per
// sequence, every step against the same W_h), where a packing GEMM would copy the weights on every call.
// The weights are packed once into column panels (gemm_pack, gemm_packed_floats of them), then
//   y[m, n] += sum_k x[m, k] b[k, n]   for m < rows, n < n_out, k < k_in
// streams them once per few rows. Row strides ldx, ldy in floats. Each y[m, n] is one fma chain over k in
// order, starting from its old value: the vector and scalar paths give the same bits, and a row's result
// does not depend on how many rows there are.
// b [k_in, n_out] is w (row-major, row stride ldw) or, with transpose, w^T for w [n_out, k_in].
size_t gemm_packed_floats(int k_in, int n_out);
void gemm_pack(const float* w, ptrdiff_t ldw, int k_in, int n_out, bool transpose, float* packed);
void gemm_acc_packed(const float* x, ptrdiff_t ldx, const float* packed, int rows, int k_in, int n_out,
                     float* y, ptrdiff_t ldy);
void gemm_acc_packed_scalar(const float* x, ptrdiff_t ldx, const float* packed, int rows, int k_in, int n_out,
                            float* y, ptrdiff_t ldy);

}  // namespace kernels
}  // namespace hns::nn
