// Adam over the flat parameter buffer (TensorFlow's form, as baselines' PPO uses it):
//   g += weight_decay * w            on kernels only (L2 penalty weight_decay / 2 * |W|^2; ParamSlice::decay)
//   g *= max_grad_norm / max(|g|, max_grad_norm)   global-norm clipping over all parameters (0: off)
//   m = b1 m + (1 - b1) g;  v = b2 v + (1 - b2) g^2
//   w -= lr * sqrt(1 - b2^t) / (1 - b1^t) * m / (sqrt(v) + eps)
// The moments live in flat buffers with the parameters' layout (easy to checkpoint and all-reduce). The
// global norm is summed in double over a fixed partition, so steps are bit-identical for any thread count.
#pragma once

#include "nn/params.hpp"

#include <cstdint>

namespace hns::nn {

struct AdamConfig {
  float lr = 3e-4f;
  float beta1 = 0.9f;
  float beta2 = 0.999f;
  float eps = 1e-8f;
  float weight_decay = 0.0f;   // paper: 1e-6
  float max_grad_norm = 0.0f;  // paper: 5; 0 disables clipping
};

struct AdamStepInfo {
  double grad_norm = 0.0;   // global norm of the gradient (weight decay included) before clipping
  float clip_scale = 1.0f;  // factor applied to the gradient
  bool applied = true;      // false if the gradient held a NaN or infinity: nothing was changed
};

class Adam {
 public:
  Adam(const ParamLayout& layout, AdamConfig cfg);

  const AdamConfig& config() const { return cfg_; }
  void set_lr(float lr) { cfg_.lr = lr; }
  int64_t steps() const { return t_; }
  // One update of params from grads (grads are modified: decay added, clipped). Both buffers have the
  // layout's buffer_floats() floats. A non-finite gradient norm skips the update (parameters, moments and
  // step count stay as they were; the caller decides whether to stop).
  AdamStepInfo step(float* params, float* grads);

  // Optimiser state, for checkpoints.
  FloatBuffer& m() { return m_; }
  FloatBuffer& v() { return v_; }
  const FloatBuffer& m() const { return m_; }
  const FloatBuffer& v() const { return v_; }
  void set_steps(int64_t t) { t_ = t; }

 private:
  AdamConfig cfg_;
  int64_t t_ = 0;
  FloatBuffer m_;      // first moment [buffer_floats]
  FloatBuffer v_;      // second moment [buffer_floats]
  FloatBuffer decay_;  // 1 where weight decay applies, else 0 [buffer_floats]
};

// Global L2 norm of n floats: the squares (exact in double) summed in double in index order within each
// block of kNormBlock floats, then the blocks' sums in block order (deterministic for any thread count).
inline constexpr size_t kNormBlock = size_t(1) << 14;
double global_norm(const float* x, size_t n);

}  // namespace hns::nn
