#include "nn/heads.hpp"

#include <array>
#include <cmath>

namespace hns::nn {
namespace {

// Log-softmax of one categorical's n logits into out (double for the log-sum-exp); returns nothing.
void log_softmax(const float* l, int n, double* out) {
  double m = l[0];
  for (int i = 1; i < n; ++i) m = std::max(m, static_cast<double>(l[i]));
  double s = 0.0;
  for (int i = 0; i < n; ++i) s += std::exp(l[i] - m);
  const double lse = m + std::log(s);
  for (int i = 0; i < n; ++i) out[i] = l[i] - lse;
}

// One head's d_logits from its log-probabilities lp, probabilities p and entropy ent (a: the action taken,
// -1 without actions). H = -sum p log p; dH/dl_k = -p_k (log p_k + H); dlogp_a/dl_k = [k == a] - p_k.
void head_gradient(const double* lp, const double* p, double ent, int n, int a, double gl, double ge,
                   float* out) {
  for (int i = 0; i < n; ++i) {
    double g = ge * (-p[i] * (lp[i] + ent));
    if (a >= 0) g += gl * ((i == a ? 1.0 : 0.0) - p[i]);
    out[i] = static_cast<float>(g);
  }
}

}  // namespace

CategoricalHeads::CategoricalHeads(std::vector<int> sizes) : sizes_(std::move(sizes)) {
  for (int s : sizes_) {
    HNS_NN_CHECK(s >= 1 && s <= kMaxChoices, "a categorical head needs 1 to kMaxChoices choices");
    offsets_.push_back(num_logits_);
    num_logits_ += s;
    max_size_ = std::max(max_size_, s);
  }
}

void CategoricalHeads::log_prob_entropy(CMat logits, const int32_t* actions, float* logp, float* entropy,
                                        double* saved) const {
  std::array<double, kMaxChoices> lp_scratch{}, p_scratch{};
  const ptrdiff_t per_row = static_cast<ptrdiff_t>(saved_doubles(1));
  for (int r = 0; r < logits.rows; ++r) {
    double sum_lp = 0.0;
    double sum_ent = 0.0;
    double* row_saved = saved != nullptr ? saved + r * per_row : nullptr;
    for (int h = 0; h < num_heads(); ++h) {
      const int n = sizes_[h];
      // With saved: the row's log-probabilities, then its probabilities, then the heads' entropies.
      double* lp = row_saved != nullptr ? row_saved + offsets_[h] : lp_scratch.data();
      double* p = row_saved != nullptr ? row_saved + num_logits_ + offsets_[h] : p_scratch.data();
      log_softmax(logits.row(r) + offsets_[h], n, lp);
      if (actions != nullptr) {
        const int a = actions[static_cast<ptrdiff_t>(r) * num_heads() + h];
        assert(a >= 0 && a < n);
        sum_lp += lp[a];
      }
      double ent = 0.0;  // this head's, as backward() sums it
      for (int i = 0; i < n; ++i) {
        p[i] = std::exp(lp[i]);
        const double plp = p[i] * lp[i];
        sum_ent -= plp;
        ent -= plp;
      }
      if (row_saved != nullptr) row_saved[2 * num_logits_ + h] = ent;
    }
    if (logp != nullptr) logp[r] = static_cast<float>(sum_lp);
    if (entropy != nullptr) entropy[r] = static_cast<float>(sum_ent);
  }
}

void CategoricalHeads::sample(CMat logits, const float* uniforms, int32_t* actions, float* logp) const {
  std::array<double, kMaxChoices> lp{};
  for (int r = 0; r < logits.rows; ++r) {
    double sum_lp = 0.0;
    for (int h = 0; h < num_heads(); ++h) {
      const int n = sizes_[h];
      log_softmax(logits.row(r) + offsets_[h], n, lp.data());
      const double u = uniforms[static_cast<ptrdiff_t>(r) * num_heads() + h];
      // First choice whose cumulative probability exceeds u; the last one if rounding leaves u above all.
      int a = n - 1;
      double cum = 0.0;
      for (int i = 0; i < n; ++i) {
        cum += std::exp(lp[i]);
        if (u < cum) {
          a = i;
          break;
        }
      }
      actions[static_cast<ptrdiff_t>(r) * num_heads() + h] = a;
      sum_lp += lp[a];
    }
    if (logp != nullptr) logp[r] = static_cast<float>(sum_lp);
  }
}

void CategoricalHeads::argmax(CMat logits, int32_t* actions) const {
  for (int r = 0; r < logits.rows; ++r) {
    for (int h = 0; h < num_heads(); ++h) {
      const float* l = logits.row(r) + offsets_[h];
      int best = 0;
      for (int i = 1; i < sizes_[h]; ++i)
        if (l[i] > l[best]) best = i;
      actions[static_cast<ptrdiff_t>(r) * num_heads() + h] = best;
    }
  }
}

void CategoricalHeads::backward(CMat logits, const int32_t* actions, const float* d_logp,
                                const float* d_entropy, Mat d_logits) const {
  std::array<double, kMaxChoices> lp{}, p{};
  for (int r = 0; r < logits.rows; ++r) {
    const double gl = d_logp != nullptr ? d_logp[r] : 0.0;
    const double ge = d_entropy != nullptr ? d_entropy[r] : 0.0;
    float* out = d_logits.row(r);
    for (int h = 0; h < num_heads(); ++h) {
      const int n = sizes_[h];
      log_softmax(logits.row(r) + offsets_[h], n, lp.data());
      // Each p_k is computed once, for the entropy and for the gradient.
      double ent = 0.0;
      for (int i = 0; i < n; ++i) {
        p[i] = std::exp(lp[i]);
        ent -= p[i] * lp[i];
      }
      const int a = actions != nullptr ? actions[static_cast<ptrdiff_t>(r) * num_heads() + h] : -1;
      head_gradient(lp.data(), p.data(), ent, n, a, gl, ge, out + offsets_[h]);
    }
  }
}

void CategoricalHeads::backward_saved(const double* saved, int rows, const int32_t* actions,
                                      const float* d_logp, const float* d_entropy, Mat d_logits) const {
  assert(d_logits.rows >= rows);
  const ptrdiff_t per_row = static_cast<ptrdiff_t>(saved_doubles(1));
  for (int r = 0; r < rows; ++r) {
    const double gl = d_logp != nullptr ? d_logp[r] : 0.0;
    const double ge = d_entropy != nullptr ? d_entropy[r] : 0.0;
    const double* row_saved = saved + r * per_row;
    for (int h = 0; h < num_heads(); ++h) {
      const int a = actions != nullptr ? actions[static_cast<ptrdiff_t>(r) * num_heads() + h] : -1;
      head_gradient(row_saved + offsets_[h], row_saved + num_logits_ + offsets_[h],
                    row_saved[2 * num_logits_ + h], sizes_[h], a, gl, ge, d_logits.row(r) + offsets_[h]);
    }
  }
}

}  // namespace hns::nn
