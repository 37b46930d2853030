#include "ppo/obs_arrays.hpp"

#include "nn/kernels.hpp"

#include <cstring>

namespace hns::ppo {

nn::ObsShape obs_shape(const batch::Layout& L) {
  nn::ObsShape o;
  o.self_features = batch::Layout::kSelfFeatures;
  o.max_agents = L.max_agents;
  o.agent_features = batch::Layout::kAgentFeatures;
  o.max_boxes = L.max_boxes;
  o.box_features = batch::Layout::kBoxFeatures;
  o.max_ramps = L.max_ramps;
  o.ramp_features = batch::Layout::kRampFeatures;
  o.max_sites = L.max_sites;
  o.site_features = L.max_sites > 0 ? L.site_features : 0;
  o.lidar_rays = batch::Layout::kLidar;
  return o;
}

StepObsView StepObsView::of(const batch::BatchState& s) {
  StepObsView v;
  v.self = s.obs_self.data();
  v.lidar = s.lidar.data();
  v.agents = s.obs_agents.data();
  v.boxes = s.obs_boxes.data();
  v.ramps = s.obs_ramps.data();
  v.sites = s.obs_sites.data();
  v.mask_agents = s.mask_agents.data();
  v.mask_boxes = s.mask_boxes.data();
  v.mask_ramps = s.mask_ramps.data();
  v.mask_sites = s.mask_sites.data();
  v.value_mask_agents = s.value_mask_agents.data();
  v.value_mask_boxes = s.value_mask_boxes.data();
  v.value_mask_ramps = s.value_mask_ramps.data();
  v.value_mask_sites = s.value_mask_sites.data();
  v.step_count = s.step_count.data();
  v.episode = s.episode.data();
  return v;
}

void ObsArrays::copy_step(const StepObsView& s, const nn::ObsShape& shape, size_t rows, size_t row0,
                          const nn::ObsNormView* norm) {
  int key = 0;  // the order of the copies below: self, lidar, agents, boxes, ramps, sites
  auto copy = [&](nn::FloatBuffer& dst, const float* src, size_t per_row, size_t features) {
    const int k = key++;
    if (per_row == 0) return;
    float* to = dst.data() + row0 * per_row;
    if (norm == nullptr) {
      std::memcpy(to, src, sizeof(float) * rows * per_row);
    } else {
      nn::kernels::normalize_obs(src, norm->mean[k], norm->inv_std[k], nullptr,
                                 int(rows * per_row / features), int(features), to);
    }
  };
  auto widen = [&](nn::FloatBuffer& dst, const uint8_t* p, size_t per_row) {
    float* d = dst.data() + row0 * per_row;
    for (size_t i = 0; i < rows * per_row; ++i) d[i] = float(p[i]);
  };
  const size_t na = size_t(shape.num_other_agents());
  copy(self, s.self, shape.self_features, shape.self_features);
  copy(lidar, s.lidar, shape.lidar_rays, shape.lidar_rays);
  copy(agents, s.agents, na * shape.agent_features, shape.agent_features);
  copy(boxes, s.boxes, size_t(shape.max_boxes) * shape.box_features, shape.box_features);
  copy(ramps, s.ramps, size_t(shape.max_ramps) * shape.ramp_features, shape.ramp_features);
  copy(sites, s.sites, size_t(shape.max_sites) * shape.site_features, shape.site_features);
  widen(agents_seen, s.mask_agents, na);
  widen(boxes_seen, s.mask_boxes, shape.max_boxes);
  widen(ramps_seen, s.mask_ramps, shape.max_ramps);
  widen(sites_seen, s.mask_sites, shape.max_sites);
  widen(agents_present, s.value_mask_agents, na);
  widen(boxes_present, s.value_mask_boxes, shape.max_boxes);
  widen(ramps_present, s.value_mask_ramps, shape.max_ramps);
  widen(sites_present, s.value_mask_sites, shape.max_sites);
}

}  // namespace hns::ppo
