// What every single-agent task of docs/game.md §9 shares (SingleAgentTask, task.hpp): the absorbed rest of a
// completed episode, the out-of-bounds override, zero for padding slots, agent 0's return and the horizon.
#include "batch/tasks/task.hpp"

#include <algorithm>

namespace hns::batch {

void SingleAgentTask::reward_and_done(EnvRef& ref) const {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const int n = ref.world.num_agents();
  const float* pos = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
  float* reward = s.reward.data() + size_t(env) * L.max_agents;
  // A completed blueprint absorbs the rest of its episode: reward 0, whatever happens (the trainer leaves
  // those steps out).
  const bool absorbed = s.task_complete[env] != 0;
  if (absorbed) {
    std::fill_n(reward, L.max_agents, 0.0f);
  } else {
    this->reward(ref, reward);
  }
  for (int a = 0; a < L.max_agents; ++a) {
    if (!absorbed && a < n && out_of_bounds(ref.config.world, pos + 3 * a)) reward[a] = kOutOfBoundsReward;
    if (a >= n) reward[a] = 0.0f;
  }
  s.episode_return[size_t(env) * 2] += reward[0];
  s.done[env] = ref.world.done() ? 1 : 0;
}

}  // namespace hns::batch
