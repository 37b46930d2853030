// The arithmetic of PPO with windowed GAE (paper appendix B), as free functions over spans:
// advantage and value targets per window, advantage z-scoring, the clipped surrogate and value losses with
// their gradients, and the diagnostics the trainer reports. No allocation; masked entries (padding agents)
// take no part in any mean and get zero gradient.
#pragma once

#include <cstdint>
#include <span>

namespace hns::ppo {

struct GaeParams {
  double gamma = 0.998;  // discount per env step
  double lambda = 0.95;  // GAE λ
};

// One window of T consecutive steps of one agent (paper appendix B: windows of T steps cut from concatenated
// episodes). rewards[t], values[t] = V(s_t) for t < T, values[T] = V(s_T) (the state after the window,
// used only if the episode goes on), last[t] = 1 if step t ended its episode (then nothing after t is used,
// as V = 0 beyond an episode's last step). Writes the advantages Â_t^H (H = steps left in the window and the
// episode) and the TD(λ) value targets Ĝ_t = Â_t + V(s_t).
void gae_window(std::span<const float> rewards, std::span<const float> values, std::span<const uint8_t> last,
                const GaeParams& params, std::span<float> advantages, std::span<float> returns);

// Z-scores x in place over the entries with mask 1 (mean 0, standard deviation 1; eps guards a constant x).
void zscore(std::span<float> x, std::span<const uint8_t> mask, float eps = 1e-8f);
// The same with the mean and standard deviation given (taken over more entries than x holds): x = (x - mean)
// / (std + eps) where mask is 1, else 0.
void zscore_with(std::span<float> x, std::span<const uint8_t> mask, double mean, double std,
                 float eps = 1e-8f);

struct PolicyLossStats {
  double loss = 0;  // -mean(min(l·A, clip(l, 1-ε, 1+ε)·A))
  // mean((r - 1) - log r) with r = exp(new_logp - old_logp): an estimate of KL(old || new), never negative.
  double approx_kl = 0;
  double clip_frac = 0;  // share of entries whose ratio left [1-ε, 1+ε]
  int64_t count = 0;     // entries with mask 1
};

// Clipped surrogate over N entries. Writes d loss / d new_logp into grad_logp (zero where masked or clipped).
PolicyLossStats ppo_policy_loss(std::span<const float> new_logp, std::span<const float> old_logp,
                                std::span<const float> advantages, std::span<const uint8_t> mask,
                                float clip_eps, std::span<float> grad_logp);

// 0.5·mean((pred - target)²) over entries with mask 1, both in normalised units (docs/game.md §10.2). Writes
// d loss / d pred into grad_pred.
double value_loss(std::span<const float> pred, std::span<const float> target, std::span<const uint8_t> mask,
                  std::span<float> grad_pred);

// 1 - Var(target - pred) / Var(target) over entries with mask 1 (0 when the targets are constant).
double explained_variance(std::span<const float> pred, std::span<const float> target,
                          std::span<const uint8_t> mask);

}  // namespace hns::ppo
