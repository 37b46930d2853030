// The trainer's composed minibatch loss (ppo_chunk_loss: clipped surrogate + value loss - entropy bonus,
// through the categorical heads and both networks): its gradient against central differences of the loss
// itself, on a tiny network, with padding rows, clipped and unclipped ratios and several chunks.
#include "ppo/ppo_loss.hpp"

#include "../nn/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace hns::ppo {
namespace {

using nn::testing::random_mask;
using nn::testing::random_vector;

// The nn tests' tiny network, with a third action head.
nn::NetConfig tiny_net() {
  nn::NetConfig c = nn::testing::tiny_net_config();
  c.action_heads = {3, 2, 4};
  return c;
}

TEST(PpoLoss, ComposedLossGradientMatchesFiniteDifferences) {
  const nn::NetConfig cfg = tiny_net();
  nn::ParallelConfig par;
  par.train_chunk_sequences = 2;  // 3 chunks: the minibatch mean spans chunks
  par.grad_groups = 2;
  nn::ActorCritic ac(cfg, par);
  ac.params().init(5);
  const auto jitter = random_vector(ac.params().buffer_floats(), 6, -0.2f, 0.2f);
  for (size_t i = 0; i < jitter.size(); ++i) ac.params().values()[i] += jitter[i];
  const nn::ObsShape& s = cfg.obs;
  const int seqs = 6, steps = 3, rows = seqs * steps;
  const int na = s.num_other_agents();
  const auto self = random_vector(size_t(rows) * s.self_features, 11, -2.0f, 2.0f);
  const auto lidar = random_vector(size_t(rows) * s.lidar_rays, 12, 0.0f, 6.0f);
  const auto agents = random_vector(size_t(rows) * na * s.agent_features, 13, -2.0f, 2.0f);
  const auto boxes = random_vector(size_t(rows) * s.max_boxes * s.box_features, 14, -2.0f, 2.0f);
  const auto ramps = random_vector(size_t(rows) * s.max_ramps * s.ramp_features, 15, -2.0f, 2.0f);
  const auto sites = random_vector(size_t(rows) * s.max_sites * s.site_features, 25, -2.0f, 2.0f);
  const auto agents_seen = random_mask(size_t(rows) * na, 16);
  const auto boxes_seen = random_mask(size_t(rows) * s.max_boxes, 17);
  const auto reset = random_mask(rows, 18, 0.2);
  nn::ObsBatch obs;
  obs.self = self.data(), obs.lidar = lidar.data(), obs.agents = agents.data();
  obs.boxes = boxes.data(), obs.ramps = ramps.data(), obs.sites = sites.data();
  obs.agents_seen = agents_seen.data(), obs.boxes_seen = boxes_seen.data(), obs.reset = reset.data();
  const nn::ObsNormalizer norm(s);
  const auto state_p = random_vector(size_t(seqs) * ac.state_width(), 19);
  const auto state_v = random_vector(size_t(seqs) * ac.state_width(), 20);

  // Actions drawn per head; the rollout's log-probabilities are today's plus noise, so some ratios leave
  // [1 - clip, 1 + clip] and some do not; two padding rows.
  const nn::CategoricalHeads& heads = ac.heads();
  std::vector<int32_t> actions(size_t(rows) * heads.num_heads());
  const auto u = random_vector(actions.size(), 21, 0.0f, 1.0f);
  for (int r = 0; r < rows; ++r)
    for (int h = 0; h < heads.num_heads(); ++h) {
      const size_t i = size_t(r) * heads.num_heads() + h;
      actions[i] = std::min(int32_t(u[i] * float(cfg.action_heads[h])), int32_t(cfg.action_heads[h] - 1));
    }
  std::vector<uint8_t> mask(rows, 1);
  mask[4] = mask[rows - 1] = 0;
  std::vector<float> logp_now(rows);
  std::vector<float> grads(ac.params().buffer_floats());
  {
    std::vector<float> entropy(rows);
    nn::LossFn record = [&](const nn::ChunkOutputs& out, const nn::ChunkGrads& g, std::span<double>) {
      heads.log_prob_entropy(out.logits, actions.data() + size_t(out.first_row) * heads.num_heads(),
                             logp_now.data() + out.first_row, entropy.data() + out.first_row);
      for (int r = 0; r < out.rows; ++r) {
        for (int k = 0; k < heads.num_logits(); ++k) g.d_logits.at(r, k) = 0.0f;
        g.d_value[r] = 0.0f;
      }
    };
    std::vector<double> none(1);
    ac.forward_backward(norm.view(), obs, seqs, steps, state_p.data(), state_v.data(), record, none,
                        grads.data());
  }
  const auto noise = random_vector(rows, 22, -0.5f, 0.5f);
  std::vector<float> old_logp(rows);
  for (int r = 0; r < rows; ++r) old_logp[r] = logp_now[r] + noise[r];
  const auto adv = random_vector(rows, 23, -1.5f, 1.5f);
  const auto ret = random_vector(rows, 24, -1.0f, 1.0f);
  int count = 0;
  for (uint8_t m : mask) count += m;
  // Coefficients large enough that each of the three terms moves the check.
  const PpoMinibatch mb{actions.data(), old_logp.data(), adv.data(), ret.data(), mask.data(), 0.2f, 0.3, 0.7,
                        1.0 / count};

  std::vector<double> stats(kNumPpoStats);
  nn::LossFn loss = [&](const nn::ChunkOutputs& out, const nn::ChunkGrads& g, std::span<double> st) {
    thread_local PpoLossScratch scratch;
    ppo_chunk_loss(heads, mb, out, g, scratch, st);
  };
  auto eval = [&]() {
    ac.forward_backward(norm.view(), obs, seqs, steps, state_p.data(), state_v.data(), loss, stats,
                        grads.data());
    return ppo_total_loss(stats, mb);
  };
  eval();
  EXPECT_EQ(stats[kCount], count);
  EXPECT_GT(stats[kClipped], 0.0);          // some ratios clipped ...
  EXPECT_LT(stats[kClipped], count - 2.0);  // ... most not
  const std::vector<float> analytic = grads;
  int coords = 0, skipped = 0;
  double err2 = 0.0, ref2 = 0.0;
  for (const nn::testing::SliceCheck& c :
       nn::testing::check_param_gradient(ac.params().values(), ac.params().layout(), analytic, 4, eval)) {
    coords += c.coords;
    skipped += c.skipped;
    err2 += c.err2;
    ref2 += c.ref2;
  }
  EXPECT_GT(ref2, 1e-4);
  EXPECT_LT(std::sqrt(err2), 0.01 * std::sqrt(ref2)) << "over " << coords - skipped << " coordinates";
  EXPECT_LT(skipped, coords / 10);
}

}  // namespace
}  // namespace hns::ppo
