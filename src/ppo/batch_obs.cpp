#include "ppo/batch_obs.hpp"

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
#define HNS_VIEW_OBS_FIELD(name, member, type, axis, key) v.name = s.name.data();
  HNS_OBS_FIELDS(HNS_VIEW_OBS_FIELD)
#undef HNS_VIEW_OBS_FIELD
  v.step_count = s.step_count.data();
  v.episode = s.episode.data();
  return v;
}

}  // namespace hns::ppo
