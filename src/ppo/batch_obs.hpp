// The batch's observations as the networks see them: their shape for a batch layout, and a batch step's
// observation fields (nn's HNS_OBS_FIELDS, the same names in BatchState, checked here at compile time) as
// the nn::StepObs that nn::ObsStore copies from.
#pragma once

#include <type_traits>

#include "batch/batch_sim.hpp"
#include "nn/obs_store.hpp"

namespace hns::ppo {

// Every observation field of nn's list is a BatchState field of the same name and element type.
#define HNS_CHECK_OBS_FIELD(name, member, type, axis, key)                              \
  static_assert(std::is_same_v<decltype(batch::BatchState::name), AlignedBuffer<type>>, \
                "nn's observation field " #name " is not a BatchState field of element type " #type);
HNS_OBS_FIELDS(HNS_CHECK_OBS_FIELD)
#undef HNS_CHECK_OBS_FIELD

// The networks' observation shape for a batch of this layout.
nn::ObsShape obs_shape(const batch::Layout& layout);

// One batch step's observations and masks as the batch lays them out (env-major, max_agents rows per env),
// wherever they are held (a BatchSim's state, or arrays a caller owns: the Python module's Policy.act), and
// the two per-env counters a policy reads. Rows = envs x max_agents.
struct StepObsView : nn::StepObs {
  const int32_t* step_count = nullptr;  // [envs] env steps taken in the current episode (0: first step)
  const int32_t* episode = nullptr;     // [envs] episode number of the env

  static StepObsView of(const batch::BatchState& s);
};

}  // namespace hns::ppo
