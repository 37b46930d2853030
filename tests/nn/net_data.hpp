// Network inputs and outputs shared by the nn tests: random observations in the trainer's store, a fitted
// normaliser, and one forward_backward with fixed output gradients.
#pragma once

#include "nn/actor_critic.hpp"
#include "nn/obs_normalizer.hpp"
#include "nn/obs_store.hpp"

#include "test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <span>
#include <vector>

namespace hns::nn::testing {

// Random observations for `rows` agent-steps in the observation store the trainer uses (nn::ObsStore);
// present masks have padding slots, seen masks are subsets. Copyable, so that a test can change a copy.
struct ObsData : ObsStore {
  ObsData(const ObsShape& s, int rows, uint64_t seed, double p_reset = 0.15) : ObsStore(s, size_t(rows)) {
    const int na = s.num_other_agents();
    fill(self, random_vector(static_cast<size_t>(rows) * s.self_features, seed + 1, -2.0f, 2.0f));
    fill(lidar, random_vector(static_cast<size_t>(rows) * s.lidar_rays, seed + 2, 0.0f, 6.0f));
    fill(agents, random_vector(static_cast<size_t>(rows) * na * s.agent_features, seed + 3, -2.0f, 2.0f));
    fill(boxes,
         random_vector(static_cast<size_t>(rows) * s.max_boxes * s.box_features, seed + 4, -2.0f, 2.0f));
    fill(ramps,
         random_vector(static_cast<size_t>(rows) * s.max_ramps * s.ramp_features, seed + 5, -2.0f, 2.0f));
    fill(sites,
         random_vector(static_cast<size_t>(rows) * s.max_sites * s.site_features, seed + 10, -2.0f, 2.0f));
    for (FloatBuffer* present : {&agents_present, &boxes_present, &ramps_present, &sites_present})
      std::fill_n(present->data(), present->size(), 1.0f);
    for (int r = 0; r < rows; ++r) {
      if (r % 3 == 0 && na > 0) agents_present[static_cast<size_t>(r) * na + na - 1] = 0.0f;
      if (r % 2 == 0 && s.max_boxes > 0)
        boxes_present[static_cast<size_t>(r) * s.max_boxes + s.max_boxes - 1] = 0.0f;
      if (r % 4 == 1 && s.max_sites > 0)
        sites_present[static_cast<size_t>(r) * s.max_sites + s.max_sites - 1] = 0.0f;
    }
    fill(agents_seen, random_mask(agents_present.size(), seed + 6, 0.6));
    fill(boxes_seen, random_mask(boxes_present.size(), seed + 7, 0.6));
    fill(ramps_seen, random_mask(ramps_present.size(), seed + 8, 0.6));
    for (size_t i = 0; i < agents_seen.size(); ++i) agents_seen[i] *= agents_present[i];
    for (size_t i = 0; i < boxes_seen.size(); ++i) boxes_seen[i] *= boxes_present[i];
    fill(sites_seen, random_mask(sites_present.size(), seed + 11, 0.7));
    for (size_t i = 0; i < sites_seen.size(); ++i) sites_seen[i] *= sites_present[i];
    fill(reset, random_mask(rows, seed + 9, p_reset));
  }
  ObsData(const ObsData& o) : ObsStore(o.shape(), o.rows()) {
#define HNS_OBS_DATA_COPY(name, member, type, axis, key) copy(o.member, member);
    HNS_OBS_FIELDS(HNS_OBS_DATA_COPY)
#undef HNS_OBS_DATA_COPY
    copy(o.reset, reset);
  }
  static void fill(FloatBuffer& dst, const std::vector<float>& src) {
    ASSERT_EQ(dst.size(), src.size());
    std::copy(src.begin(), src.end(), dst.data());
  }
  static void copy(const FloatBuffer& src, FloatBuffer& dst) {
    std::copy_n(src.data(), src.size(), dst.data());
  }
};

// A normaliser that has seen the data once (so normalisation is not the identity).
inline ObsNormalizer fitted_normalizer(const ObsShape& s, const ObsData& d, int rows) {
  ObsNormalizer n(s);
  n.update(d.self.data(), d.lidar.data(), d.agents.data(), d.boxes.data(), d.ramps.data(), d.sites.data(),
           rows);
  return n;
}

// Logits, values and parameter gradients of one forward_backward over seqs x steps rows, with fixed output
// gradients: d logit k = a (k + 1) + b, d value = c.
struct Result {
  std::vector<float> logits, value, grads;
};
inline Result outputs_and_grads(ActorCritic& ac, const ObsNormView& view, const ObsBatch& obs, int seqs,
                                int steps, float a, float b, float c) {
  const int rows = seqs * steps, nl = ac.heads().num_logits();
  Result res;
  res.logits.resize(static_cast<size_t>(rows) * nl);
  res.value.resize(rows);
  res.grads.resize(ac.params().buffer_floats());
  std::vector<double> stats;
  ac.forward_backward(
      view, obs, seqs, steps, nullptr, nullptr,
      [&](const ChunkOutputs& out, const ChunkGrads& g, std::span<double>) {
        for (int r = 0; r < out.rows; ++r) {
          for (int k = 0; k < nl; ++k) {
            res.logits[(out.first_row + r) * nl + k] = out.logits.at(r, k);
            g.d_logits.at(r, k) = a * static_cast<float>(k + 1) + b;
          }
          res.value[out.first_row + r] = out.value[r];
          g.d_value[r] = c;
        }
      },
      stats, res.grads.data());
  return res;
}

}  // namespace hns::nn::testing
