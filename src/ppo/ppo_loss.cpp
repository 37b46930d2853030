#include "ppo/ppo_loss.hpp"

#include "ppo/ppo_math.hpp"

namespace hns::ppo {

void ppo_chunk_loss(const nn::CategoricalHeads& heads, const PpoMinibatch& mb, const nn::ChunkOutputs& out,
                    const nn::ChunkGrads& g, PpoLossScratch& ls, std::span<double> stats) {
  const size_t n = size_t(out.rows);
  for (auto* v : {&ls.new_logp, &ls.entropy, &ls.grad_logp, &ls.d_entropy, &ls.grad_value})
    if (v->size() < n) v->resize(n);
  const int r0 = out.first_row;
  const int32_t* act = mb.actions + size_t(r0) * heads.num_heads();
  if (ls.heads_saved.size() < heads.saved_doubles(out.logits.rows))
    ls.heads_saved.resize(heads.saved_doubles(out.logits.rows));
  heads.log_prob_entropy(out.logits, act, ls.new_logp.data(), ls.entropy.data(), ls.heads_saved.data());
  const std::span<const uint8_t> mask(mb.mask + r0, n);
  const PolicyLossStats ps =
      ppo_policy_loss({ls.new_logp.data(), n}, {mb.old_logp + r0, n}, {mb.advantages + r0, n}, mask, mb.clip,
                      {ls.grad_logp.data(), n});
  const double vl = value_loss({out.value, n}, {mb.returns + r0, n}, mask, {ls.grad_value.data(), n});
  // ppo_math's means are over this chunk's entries; rescale to the minibatch mean.
  const float pscale = float(double(ps.count) * mb.inv_total);
  const float vscale = float(mb.value_coef * double(ps.count) * mb.inv_total);
  double ent = 0;
  for (size_t i = 0; i < n; ++i) {
    ls.grad_logp[i] *= pscale;
    g.d_value[i] = ls.grad_value[i] * vscale;
    ls.d_entropy[i] = mask[i] != 0 ? float(-mb.entropy_coef * mb.inv_total) : 0.0f;
    if (mask[i] != 0) ent += ls.entropy[i];
  }
  heads.backward_saved(ls.heads_saved.data(), out.rows, act, ls.grad_logp.data(), ls.d_entropy.data(),
                       g.d_logits);
  stats[kPolicyLoss] += ps.loss * double(ps.count);
  stats[kValueLoss] += vl * double(ps.count);
  stats[kEntropy] += ent;
  stats[kKl] += ps.approx_kl * double(ps.count);
  stats[kClipped] += ps.clip_frac * double(ps.count);
  stats[kCount] += double(ps.count);
}

double ppo_total_loss(std::span<const double> stats, const PpoMinibatch& mb) {
  return (stats[kPolicyLoss] + mb.value_coef * stats[kValueLoss] - mb.entropy_coef * stats[kEntropy]) *
         mb.inv_total;
}

}  // namespace hns::ppo
