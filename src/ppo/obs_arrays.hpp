// Observation arrays in the float layout the networks read (nn::ObsBatch), for any number of agent rows,
// and the copy of one batch step's observations and masks into them.
#pragma once

#include "batch/batch_sim.hpp"
#include "nn/actor_critic.hpp"

namespace hns::ppo {

// The networks' observation shape for a batch of this layout.
nn::ObsShape obs_shape(const batch::Layout& layout);

// One batch step's observations and masks as the batch lays them out (BatchState's obs_* and mask fields,
// env-major, max_agents rows per env), wherever they are held: a BatchSim's state, or arrays a caller owns
// (the Python module's Policy.act). Rows = envs x max_agents.
struct StepObsView {
  const float* self = nullptr;                 // [rows, 11]
  const float* lidar = nullptr;                // [rows, 30]
  const float* agents = nullptr;               // [rows, A - 1, 11]
  const float* boxes = nullptr;                // [rows, B, 15]
  const float* ramps = nullptr;                // [rows, R, 12]
  const float* sites = nullptr;                // [rows, C, Fc] (the layout's sites; null without)
  const uint8_t* mask_agents = nullptr;        // [rows, A - 1] policy masks, 0/1
  const uint8_t* mask_boxes = nullptr;         // [rows, B]
  const uint8_t* mask_ramps = nullptr;         // [rows, R]
  const uint8_t* mask_sites = nullptr;         // [rows, C]
  const uint8_t* value_mask_agents = nullptr;  // [rows, A - 1] value masks, 0/1
  const uint8_t* value_mask_boxes = nullptr;   // [rows, B]
  const uint8_t* value_mask_ramps = nullptr;   // [rows, R]
  const uint8_t* value_mask_sites = nullptr;   // [rows, C]
  const int32_t* step_count = nullptr;  // [envs] env steps taken in the current episode (0: first step)
  const int32_t* episode = nullptr;     // [envs] episode number of the env

  static StepObsView of(const batch::BatchState& s);
};

// One set of per-row observation arrays, `rows` rows (the trainer's rollout: T x G step-major, normalised;
// Policy: one step, normalised).
struct ObsArrays {
  // Copies the observations and masks of every agent row of the batch's current step (rows = envs x max
  // agents) into rows [row0, row0 + rows), normalised and clipped on the way when `norm` is given (the
  // networks then read them with ObsNormView::identity()); masks widened to floats; the reset flags are left
  // to the caller.
  void copy_step(const StepObsView& s, const nn::ObsShape& shape, size_t rows, size_t row0,
                 const nn::ObsNormView* norm = nullptr);

  nn::FloatBuffer self, lidar, agents, boxes, ramps, sites;
  nn::FloatBuffer agents_seen, boxes_seen, ramps_seen, sites_seen;
  nn::FloatBuffer agents_present, boxes_present, ramps_present, sites_present;
  nn::FloatBuffer reset;

  // Floats per row over all the arrays (what allocate takes per row).
  static size_t floats_per_row(const nn::ObsShape& s) {
    const size_t na = s.num_other_agents();
    const size_t entities = na + size_t(s.max_boxes) + size_t(s.max_ramps) + size_t(s.max_sites);
    return size_t(s.self_features) + size_t(s.lidar_rays) + na * s.agent_features +
           size_t(s.max_boxes) * s.box_features + size_t(s.max_ramps) * s.ramp_features +
           size_t(s.max_sites) * s.site_features + 2 * entities + 1;
  }
  void allocate(const nn::ObsShape& s, size_t rows) {
    const size_t na = s.num_other_agents();
    self.resize(rows * s.self_features);
    lidar.resize(rows * s.lidar_rays);
    agents.resize(rows * na * s.agent_features);
    boxes.resize(rows * s.max_boxes * s.box_features);
    ramps.resize(rows * s.max_ramps * s.ramp_features);
    sites.resize(rows * s.max_sites * s.site_features);
    agents_seen.resize(rows * na);
    boxes_seen.resize(rows * s.max_boxes);
    ramps_seen.resize(rows * s.max_ramps);
    sites_seen.resize(rows * s.max_sites);
    agents_present.resize(rows * na);
    boxes_present.resize(rows * s.max_boxes);
    ramps_present.resize(rows * s.max_ramps);
    sites_present.resize(rows * s.max_sites);
    reset.resize(rows);
  }
  nn::ObsBatch batch() const {
    nn::ObsBatch b;
    b.self = self.data();
    b.lidar = lidar.data();
    b.agents = agents.data();
    b.boxes = boxes.data();
    b.ramps = ramps.data();
    b.sites = sites.data();
    b.agents_seen = agents_seen.data();
    b.boxes_seen = boxes_seen.data();
    b.ramps_seen = ramps_seen.data();
    b.sites_seen = sites_seen.data();
    b.agents_present = agents_present.data();
    b.boxes_present = boxes_present.data();
    b.ramps_present = ramps_present.data();
    b.sites_present = sites_present.data();
    b.reset = reset.data();
    return b;
  }
};

}  // namespace hns::ppo
