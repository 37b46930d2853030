#include "nn/adam.hpp"

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/parallel_for.h>

#include <cmath>
#include <vector>

namespace hns::nn {
namespace {

constexpr size_t kBlock = 1 << 14;  // floats per reduction block and per parallel task

// Calls f(begin, end) on consecutive blocks of [0, n) in parallel.
template <class F>
void for_blocks(size_t n, F&& f) {
  const size_t blocks = (n + kBlock - 1) / kBlock;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t b = r.begin(); b < r.end(); ++b) f(b * kBlock, std::min(n, (b + 1) * kBlock));
  });
}

}  // namespace

double global_norm(const float* x, size_t n) {
  const size_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<double> partial(blocks, 0.0);
  for_blocks(n, [&](size_t begin, size_t end) {
    double s = 0.0;
    for (size_t i = begin; i < end; ++i) s += static_cast<double>(x[i]) * x[i];
    partial[begin / kBlock] = s;
  });
  double s = 0.0;
  for (double p : partial) s += p;
  return std::sqrt(s);
}

Adam::Adam(const ParamLayout& layout, AdamConfig cfg)
    : cfg_(cfg), m_(layout.buffer_floats()), v_(layout.buffer_floats()), decay_(layout.buffer_floats()) {
  for (const ParamSlice& s : layout.slices())
    if (s.decay)
      for (size_t i = 0; i < s.size(); ++i) decay_[s.offset + i] = 1.0f;
}

AdamStepInfo Adam::step(float* params, float* grads) {
  const size_t n = m_.size();
  AdamStepInfo info;
  if (cfg_.weight_decay != 0.0f) {
    const float wd = cfg_.weight_decay;
    for_blocks(n, [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) grads[i] += wd * decay_[i] * params[i];
    });
  }
  info.grad_norm = global_norm(grads, n);
  if (!std::isfinite(info.grad_norm)) {
    info.applied = false;
    return info;
  }
  if (cfg_.max_grad_norm > 0.0f && info.grad_norm > cfg_.max_grad_norm)
    info.clip_scale = static_cast<float>(cfg_.max_grad_norm / info.grad_norm);
  ++t_;
  const double bc1 = 1.0 - std::pow(static_cast<double>(cfg_.beta1), static_cast<double>(t_));
  const double bc2 = 1.0 - std::pow(static_cast<double>(cfg_.beta2), static_cast<double>(t_));
  const float lr_t = static_cast<float>(cfg_.lr * std::sqrt(bc2) / bc1);
  const float b1 = cfg_.beta1, b2 = cfg_.beta2, eps = cfg_.eps, scale = info.clip_scale;
  float* m = m_.data();
  float* v = v_.data();
  for_blocks(n, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const float g = grads[i] * scale;
      grads[i] = g;
      m[i] = b1 * m[i] + (1.0f - b1) * g;
      v[i] = b2 * v[i] + (1.0f - b2) * g * g;
      params[i] -= lr_t * m[i] / (std::sqrt(v[i]) + eps);
    }
  });
  return info;
}

}  // namespace hns::nn
