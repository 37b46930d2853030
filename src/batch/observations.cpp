// Observations: the tensors and masks every agent's policy and value function read (docs/game.md §4.3-§4.6,
// §14.1), written from the mirror and this step's vision after the rules ran. Other agents come in circulant
// order i-1, i-2, ... (mod n); boxes and ramps in index order; padding slots are zero with mask 0.
#include <algorithm>
#include <cmath>

#include "batch/tasks/task.hpp"

namespace hns::batch {
namespace {

// prep_obs after t steps of an episode with `prep` preparation steps (docs/game.md §4.3): t / (prep + 1e-5),
// which first reads 1 after step prep + 1. Rounded to float that quotient would read 1 a step early once prep
// exceeds a few hundred, so it is capped just below 1 until then.
float prep_observation(int t, int prep) {
  if (t > prep) return 1.0f;
  return std::min(float(double(t) / (double(prep) + 1e-5)), std::nextafter(1.0f, 0.0f));
}

// Every observation tensor and mask of the env to zero (and the food variants' eating mask).
void clear_observations(EnvRef& ref) {
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const int A = L.max_agents, B = L.max_boxes, R = L.max_ramps, O = L.others;
  const int C = L.max_sites, F = L.max_food, SF = L.site_features;
  const size_t ea = size_t(ref.index) * A;
  std::fill_n(s.food_eat_ok.data() + ea * F, size_t(A) * F, 0);
  std::fill_n(s.obs_self.data() + ea * Layout::kSelfFeatures, size_t(A) * Layout::kSelfFeatures, 0.0f);
  std::fill_n(s.obs_agents.data() + ea * O * Layout::kAgentFeatures, size_t(A) * O * Layout::kAgentFeatures,
              0.0f);
  std::fill_n(s.mask_agents.data() + ea * O, size_t(A) * O, 0);
  std::fill_n(s.value_mask_agents.data() + ea * O, size_t(A) * O, 0);
  std::fill_n(s.obs_boxes.data() + ea * B * Layout::kBoxFeatures, size_t(A) * B * Layout::kBoxFeatures, 0.0f);
  std::fill_n(s.mask_boxes.data() + ea * B, size_t(A) * B, 0);
  std::fill_n(s.value_mask_boxes.data() + ea * B, size_t(A) * B, 0);
  std::fill_n(s.obs_ramps.data() + ea * R * Layout::kRampFeatures, size_t(A) * R * Layout::kRampFeatures,
              0.0f);
  std::fill_n(s.mask_ramps.data() + ea * R, size_t(A) * R, 0);
  std::fill_n(s.value_mask_ramps.data() + ea * R, size_t(A) * R, 0);
  std::fill_n(s.obs_sites.data() + ea * C * SF, size_t(A) * C * SF, 0.0f);
  std::fill_n(s.mask_sites.data() + ea * C, size_t(A) * C, 0);
  std::fill_n(s.value_mask_sites.data() + ea * C, size_t(A) * C, 0);
}

// Every agent's own features and its rows of the other agents, the boxes and the ramps.
void observe_bodies(EnvRef& ref) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const int A = L.max_agents, B = L.max_boxes, R = L.max_ramps, O = L.others;
  const int n = ref.world.num_agents(), nb = ref.world.num_boxes(), nr = ref.world.num_ramps();
  const size_t ea = size_t(env) * A;
  float* obs_self = s.obs_self.data() + ea * Layout::kSelfFeatures;
  float* obs_agents = s.obs_agents.data() + ea * O * Layout::kAgentFeatures;
  uint8_t* mask_agents = s.mask_agents.data() + ea * O;
  uint8_t* value_mask_agents = s.value_mask_agents.data() + ea * O;
  float* obs_boxes = s.obs_boxes.data() + ea * B * Layout::kBoxFeatures;
  uint8_t* mask_boxes = s.mask_boxes.data() + ea * B;
  uint8_t* value_mask_boxes = s.value_mask_boxes.data() + ea * B;
  float* obs_ramps = s.obs_ramps.data() + ea * R * Layout::kRampFeatures;
  uint8_t* mask_ramps = s.mask_ramps.data() + ea * R;
  uint8_t* value_mask_ramps = s.value_mask_ramps.data() + ea * R;

  const float prep_obs = prep_observation(s.step_count[env], ref.config.world.prep_steps());
  const float* pos = s.agent_pos.data() + ea * 3;
  const float* rot = s.agent_rot.data() + ea * 2;
  const float* vel = s.agent_vel.data() + ea * 3;
  const float* angvel = s.agent_angvel.data() + ea;
  const uint8_t* hider = s.agent_hider.data() + ea;
  auto agent_features = [&](int j, float* out) {
    out[0] = pos[3 * j], out[1] = pos[3 * j + 1], out[2] = pos[3 * j + 2];
    out[3] = rot[2 * j], out[4] = rot[2 * j + 1];
    out[5] = vel[3 * j], out[6] = vel[3 * j + 1], out[7] = vel[3 * j + 2];
    out[8] = angvel[j];
    out[9] = float(hider[j]);
    out[10] = prep_obs;
  };
  // Lock features of an object for agent a: it locked it, its team did, it is locked (docs/game.md §3.4).
  auto lock_features = [&](bool locked, int locker, int a, float* out) {
    out[0] = locked && locker == a ? 1.0f : 0.0f;
    out[1] = locked && locker >= 0 && hider[locker] == hider[a] ? 1.0f : 0.0f;
    out[2] = locked ? 1.0f : 0.0f;
  };
  const uint8_t* vis_agents = s.vis_agents.data() + ea * A;
  const uint8_t* vis_boxes = s.vis_boxes.data() + ea * B;
  const uint8_t* vis_ramps = s.vis_ramps.data() + ea * R;
  const int hider_obs = ref.task.hider_observation();
  for (int a = 0; a < n; ++a) {
    agent_features(a, obs_self + a * Layout::kSelfFeatures);
    if (hider_obs >= 0) obs_self[a * Layout::kSelfFeatures + 9] = float(hider_obs);
    for (int k = 0; k < n - 1; ++k) {
      const int j = ((a - 1 - k) % n + n) % n;
      agent_features(j, obs_agents + (size_t(a) * O + k) * Layout::kAgentFeatures);
      mask_agents[a * O + k] = vis_agents[a * A + j];
      value_mask_agents[a * O + k] = 1;
    }
    for (int b = 0; b < nb; ++b) {
      const size_t i = size_t(env) * B + b;
      float* out = obs_boxes + (size_t(a) * B + b) * Layout::kBoxFeatures;
      std::copy_n(s.box_pos.data() + (3 * i), 3, out);
      std::copy_n(s.box_rot.data() + (2 * i), 2, out + 3);
      std::copy_n(s.box_vel.data() + (3 * i), 3, out + 5);
      out[8] = s.box_angvel[i];
      std::copy_n(s.box_size.data() + (3 * i), 3, out + 9);
      lock_features(s.box_locked[i] != 0, s.box_locker[i], a, out + 12);
      mask_boxes[a * B + b] = vis_boxes[a * B + b];
      value_mask_boxes[a * B + b] = 1;
    }
    for (int r = 0; r < nr; ++r) {
      const size_t i = size_t(env) * R + r;
      float* out = obs_ramps + (size_t(a) * R + r) * Layout::kRampFeatures;
      std::copy_n(s.ramp_pos.data() + (3 * i), 3, out);
      std::copy_n(s.ramp_rot.data() + (2 * i), 2, out + 3);
      std::copy_n(s.ramp_vel.data() + (3 * i), 3, out + 5);
      out[8] = s.ramp_angvel[i];
      lock_features(s.ramp_locked[i] != 0, s.ramp_locker[i], a, out + 9);
      mask_ramps[a * R + r] = vis_ramps[a * R + r];
      value_mask_ramps[a * R + r] = 1;
    }
  }
}

}  // namespace

void observe(EnvRef& ref) {
  clear_observations(ref);
  observe_bodies(ref);
  ref.task.observe(ref);
}

}  // namespace hns::batch
