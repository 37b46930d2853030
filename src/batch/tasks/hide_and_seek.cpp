// The hide-and-seek game (docs/game.md §1-§7): hiders and seekers, a preparation phase in which the seekers
// cannot move, then a joint zero-sum team reward (±1 per step) and a -10 penalty out of bounds. Its presets
// are quadrant, full and empty (at the end); the food variants (food, dynamic-food) are this game with food
// items, whose rules and presets are in food.cpp. Per step it also keeps the seeking phase's statistics and
// measures what the preparation phase left (episode_stats.cpp).
#include <algorithm>

#include "batch/scenes.hpp"
#include "batch/tasks/food.hpp"
#include "batch/tasks/task.hpp"

namespace hns::batch {
namespace {

class HideAndSeek final : public Task {
 public:
  void start_episode(EnvRef& ref, uint64_t episode) const override {
    if (ref.L.max_food > 0) food_start_episode(ref, episode);
  }
  void reward_and_done(EnvRef& ref) const override;
  void observe(EnvRef& ref) const override {
    if (ref.L.max_food > 0) food_observe(ref);
  }
};

void HideAndSeek::reward_and_done(EnvRef& ref) const {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const physics::WorldConfig& wc = ref.config.world;
  const GameRules& rules = ref.config.rules;
  const physics::World& world = ref.world;
  const int t = world.step_count();
  const int n = world.num_agents();
  const float* pos = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
  const uint8_t* hider = s.agent_hider.data() + size_t(env) * L.max_agents;
  const uint8_t* vis = s.vis_agents.data() + size_t(env) * L.max_agents * L.max_agents;
  auto outside = [&rules](const float* p) { return out_of_bounds(rules, p); };

  // Joint zero-sum (docs/game.md §5.1): every hider gets -1 if any hider is seen by any seeker, else +1;
  // seekers the opposite. Out of bounds replaces an agent's reward with -10; in the quadrant game any box or
  // ramp out of bounds costs everyone -10 (§5.2). Everything is 0 during the preparation phase.
  bool any_seen = false;
  for (int sk = 0; sk < n; ++sk) {
    if (hider[sk] != 0) continue;
    for (int h = 0; h < n; ++h) any_seen = any_seen || (hider[h] != 0 && vis[sk * L.max_agents + h] != 0);
  }
  bool objects_out = false;
  if (rules.penalize_objects_out) {
    for (int b = 0; b < world.num_boxes(); ++b)
      objects_out = objects_out || outside(s.box_pos.data() + ((size_t(env) * L.max_boxes + b) * 3));
    for (int r = 0; r < world.num_ramps(); ++r)
      objects_out = objects_out || outside(s.ramp_pos.data() + ((size_t(env) * L.max_ramps + r) * 3));
  }
  const bool prep = t <= wc.prep_steps();
  float* reward = s.reward.data() + size_t(env) * L.max_agents;
  for (int a = 0; a < L.max_agents; ++a) {
    float r = 0.0f;
    if (a < n && !prep) {
      r = (hider[a] != 0) == any_seen ? -1.0f : 1.0f;
      if (objects_out || outside(pos + 3 * a)) r = kOutOfBoundsReward;
    }
    reward[a] = r;
  }
  if (L.max_food > 0) food_after_step(ref, reward, prep);  // added to the game's (its wrapper is outermost)
  float hider_sum = 0, seeker_sum = 0;
  int hiders = 0;
  for (int a = 0; a < n; ++a) {
    (hider[a] != 0 ? hider_sum : seeker_sum) += reward[a];
    hiders += hider[a];
  }
  float* ret = s.episode_return.data() + size_t(env) * 2;
  if (hiders > 0) ret[0] += hider_sum / hiders;
  if (n - hiders > 0) ret[1] += seeker_sum / (n - hiders);
  if (!prep) track_seeking(ref, any_seen);

  // Statistics at the end of the preparation phase (docs/game.md §7): when prep_obs first reads 1, after step
  // prep_steps + 1 (or at the last step of an episode too short for that).
  if (t == std::min(wc.prep_steps() + 1, wc.horizon)) {
    measure_stats(ref, s.stat_prep.data() + size_t(env) * Layout::kPrepStats);
  }
  s.done[env] = world.done() ? 1 : 0;
}

}  // namespace

const Task& hide_and_seek_task() {
  static const HideAndSeek task;
  return task;
}

// The quadrant game (docs/game.md §2.1): BatchConfig's defaults.
BatchConfig quadrant_scene() {
  BatchConfig c;
  c.world = physics::WorldConfig::quadrant();
  return c;
}

// The full game: random rooms, lockable ramps, horizon 240, an open arena whose bounds are 18 x 18 m around
// its centre, objects outside them not penalised (docs/game.md §5.2).
BatchConfig full_scene() {
  BatchConfig c;
  c.world = physics::WorldConfig::full();
  const double open_arena[4] = {-6.0, -6.0, 12.0, 12.0};
  std::copy(std::begin(open_arena), std::end(open_arena), std::begin(c.rules.restrict_rect));
  c.rules.penalize_objects_out = false;
  return c;
}

BatchConfig empty_scene() {
  BatchConfig c;
  c.world = physics::WorldConfig::empty();
  return c;
}

}  // namespace hns::batch
