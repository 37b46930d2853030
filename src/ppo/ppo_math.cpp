#include "ppo/ppo_math.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace hns::ppo {

void gae_window(std::span<const float> rewards, std::span<const float> values, std::span<const uint8_t> last,
                const GaeParams& params, std::span<float> advantages, std::span<float> returns) {
  const size_t T = rewards.size();
  assert(values.size() == T + 1 && last.size() == T && advantages.size() == T && returns.size() == T);
  // Reverse recurrence Â_t = δ_t + γλ·Â_{t+1}, cut at episode ends and at the window's end.
  double next_advantage = 0.0;
  for (size_t i = T; i-- > 0;) {
    const bool ends = last[i] != 0;
    const double next_value = ends ? 0.0 : double(values[i + 1]);
    const double delta = double(rewards[i]) + params.gamma * next_value - double(values[i]);
    const double carry = (ends || i + 1 == T) ? 0.0 : next_advantage;
    const double advantage = delta + params.gamma * params.lambda * carry;
    advantages[i] = float(advantage);
    returns[i] = float(advantage + double(values[i]));
    next_advantage = advantage;
  }
}

void zscore(std::span<float> x, std::span<const uint8_t> mask, float eps) {
  double sum = 0, sum_sq = 0;
  int64_t n = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    if (mask[i] == 0) continue;
    sum += x[i];
    sum_sq += double(x[i]) * x[i];
    ++n;
  }
  if (n == 0) return;
  const double mean = sum / n;
  zscore_with(x, mask, mean, std::sqrt(std::max(0.0, sum_sq / n - mean * mean)), eps);
}

void zscore_with(std::span<float> x, std::span<const uint8_t> mask, double mean, double std, float eps) {
  for (size_t i = 0; i < x.size(); ++i) x[i] = mask[i] != 0 ? float((x[i] - mean) / (std + eps)) : 0.0f;
}

PolicyLossStats ppo_policy_loss(std::span<const float> new_logp, std::span<const float> old_logp,
                                std::span<const float> advantages, std::span<const uint8_t> mask,
                                float clip_eps, std::span<float> grad_logp) {
  PolicyLossStats stats;
  for (uint8_t m : mask) stats.count += m != 0;
  std::fill(grad_logp.begin(), grad_logp.end(), 0.0f);
  if (stats.count == 0) return stats;
  const double inv_n = 1.0 / double(stats.count);
  double loss = 0, kl = 0;
  int64_t clipped = 0;
  for (size_t i = 0; i < new_logp.size(); ++i) {
    if (mask[i] == 0) continue;
    const double ratio = std::exp(double(new_logp[i]) - double(old_logp[i]));
    const double a = advantages[i];
    const double unclipped = ratio * a;
    const double clipped_ratio = std::clamp(ratio, 1.0 - clip_eps, 1.0 + clip_eps);
    const double surrogate = std::min(unclipped, clipped_ratio * a);
    loss -= surrogate;
    kl += (ratio - 1.0) - (double(new_logp[i]) - double(old_logp[i]));
    clipped += std::abs(ratio - 1.0) > clip_eps ? 1 : 0;
    // The gradient flows only through the unclipped term when it is the minimum: d(l·A)/d logp = l·A.
    if (unclipped <= clipped_ratio * a) grad_logp[i] = float(-unclipped * inv_n);
  }
  stats.loss = loss * inv_n;
  stats.approx_kl = kl * inv_n;
  stats.clip_frac = double(clipped) * inv_n;
  return stats;
}

double value_loss(std::span<const float> pred, std::span<const float> target, std::span<const uint8_t> mask,
                  std::span<float> grad_pred) {
  int64_t n = 0;
  for (uint8_t m : mask) n += m != 0;
  std::fill(grad_pred.begin(), grad_pred.end(), 0.0f);
  if (n == 0) return 0.0;
  double loss = 0;
  for (size_t i = 0; i < pred.size(); ++i) {
    if (mask[i] == 0) continue;
    const double d = double(pred[i]) - double(target[i]);
    loss += 0.5 * d * d;
    grad_pred[i] = float(d / double(n));
  }
  return loss / double(n);
}

double explained_variance(std::span<const float> pred, std::span<const float> target,
                          std::span<const uint8_t> mask) {
  double st = 0, st2 = 0, sr = 0, sr2 = 0;
  int64_t n = 0;
  for (size_t i = 0; i < pred.size(); ++i) {
    if (mask[i] == 0) continue;
    const double t = target[i], r = double(target[i]) - double(pred[i]);
    st += t, st2 += t * t, sr += r, sr2 += r * r;
    ++n;
  }
  if (n == 0) return 0.0;
  const double var_t = st2 / n - (st / n) * (st / n);
  const double var_r = sr2 / n - (sr / n) * (sr / n);
  return var_t > 1e-12 ? 1.0 - var_r / var_t : 0.0;
}

}  // namespace hns::ppo
