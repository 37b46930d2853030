#include "nn/adam.hpp"

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "nn/simd.hpp"

namespace hns::nn {
namespace {

constexpr size_t kBlock = kNormBlock;  // floats per reduction block and per parallel task

// Calls f(begin, end) on consecutive blocks of [0, n) in parallel.
template <class F>
void for_blocks(size_t n, F&& f) {
  const size_t blocks = (n + kBlock - 1) / kBlock;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t b = r.begin(); b < r.end(); ++b) f(b * kBlock, std::min(n, (b + 1) * kBlock));
  });
}

// Blocks whose sums one task runs side by side: each block's sum is still one chain in index order, but
// kChains independent chains hide the latency of the double adds (one chain waits on every add).
constexpr size_t kChains = 8;

}  // namespace

double global_norm(const float* x, size_t n) {
  const size_t blocks = (n + kBlock - 1) / kBlock;
  const size_t whole = n / kBlock;  // blocks of exactly kBlock floats
  std::vector<double> partial(blocks, 0.0);
  tbb::parallel_for(size_t{0}, (blocks + kChains - 1) / kChains, [&](size_t task) {
    const size_t b0 = task * kChains, b1 = std::min(blocks, b0 + kChains);
    const size_t together = std::min(b1, whole) > b0 ? std::min(b1, whole) - b0 : 0;
    if (together == kChains) {
      double s[kChains] = {};
      const float* base = x + b0 * kBlock;
      for (size_t i = 0; i < kBlock; ++i)
        for (size_t c = 0; c < kChains; ++c) {
          const double v = base[c * kBlock + i];
          s[c] += v * v;
        }
      for (size_t c = 0; c < kChains; ++c) partial[b0 + c] = s[c];
      return;
    }
    for (size_t b = b0; b < b1; ++b) {  // the last task: fewer blocks, the last one maybe short
      double s = 0.0;
      for (size_t i = b * kBlock, end = std::min(n, (b + 1) * kBlock); i < end; ++i)
        s += static_cast<double>(x[i]) * x[i];
      partial[b] = s;
    }
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
    const float* decay = decay_.data();
    for_blocks(n, [&](size_t begin, size_t end) {
      simd::for_each<true>(static_cast<int>(end - begin), [&](auto tag, int k) {
        using F = decltype(tag);
        const size_t i = begin + size_t(k);
        simd::store(grads + i,
                    simd::load<F>(grads + i) + F(wd) * simd::load<F>(decay + i) * simd::load<F>(params + i));
      });
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
  const float c1 = 1.0f - b1, c2 = 1.0f - b2;
  float* m = m_.data();
  float* v = v_.data();
  // Vectors of elements at a time; each element's arithmetic is the same IEEE operations in the same order
  // in the vector loop and its tail (simd.hpp), so the bits do not depend on where the blocks end.
  for_blocks(n, [&](size_t begin, size_t end) {
    simd::for_each<true>(static_cast<int>(end - begin), [&](auto tag, int k) {
      using F = decltype(tag);
      const size_t i = begin + size_t(k);
      const F g = simd::load<F>(grads + i) * F(scale);
      simd::store(grads + i, g);
      const F mi = F(b1) * simd::load<F>(m + i) + F(c1) * g;
      const F vi = F(b2) * simd::load<F>(v + i) + F(c2) * g * g;
      simd::store(m + i, mi);
      simd::store(v + i, vi);
      simd::store(params + i, simd::load<F>(params + i) - F(lr_t) * mi / (simd::sqrt(vi) + F(eps)));
    });
  });
  return info;
}

}  // namespace hns::nn
