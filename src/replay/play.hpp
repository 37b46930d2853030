// What `hns play` records, for every front end that records (the command line, the Python module's
// hns.record): the game a recording plays and the actions it takes.
#pragma once

#include <string>

#include "batch/scenes.hpp"
#include "ppo/policy.hpp"
#include "replay/recorder.hpp"

namespace hns::replay {

// The recording of `episodes` whole episodes on min(envs, episodes) envs side by side: the scene preset
// (empty: "quadrant", or the policy's game when there is a policy; another explicit scene than the policy's
// is a physics::ConfigError), the count overrides, `threads` worker threads (already resolved), `seed`.
// Validated (physics::ConfigError naming the field); the memory check is the caller's.
RecordConfig play_config(const std::string& scene, const ppo::Policy* policy,
                         const batch::CountOverrides& counts, int episodes, int envs, int threads,
                         uint64_t seed);

// The actions of a recording: the policy's (sampled, its streams per env and episode), or uniformly random
// ones from `seed`. The policy, when given, must outlive the returned function.
ActionFn play_actions(ppo::Policy* policy, uint64_t seed);

}  // namespace hns::replay
