// What every game shares (task.hpp): the rules' checks (GameRules::validate, game.hpp) and the worlds a task
// refuses by default; and what every single-agent task of docs/game.md §9 shares (SingleAgentTask): its
// scenes' lone hider, the absorbed rest of a completed episode, the out-of-bounds override, zero for padding
// slots, agent 0's return and the horizon.
#include "batch/tasks/task.hpp"

#include <algorithm>
#include <cmath>

namespace hns::batch {

void GameRules::validate(const physics::WorldConfig& world) const {
  if (task == nullptr)
    throw physics::ConfigError("task is invalid: the rules name no game (GameRules::task)");
  task->validate(world, *this);
  using physics::check_field;
  check_field(food.eat_radius > 0 && food.eat_radius <= 10, "food.eat_radius", food.eat_radius,
              "must be in (0, 10] m");
  check_field(food.max_health > 0 && food.max_health <= 1e6, "food.max_health", food.max_health,
              "must be in (0, 1000000] units");
  check_field(food.respawn_steps >= 0 && food.respawn_steps <= 1000000, "food.respawn_steps",
              food.respawn_steps, "must be in [0, 1000000] (0: never)");
  check_field(std::isfinite(food.reward_scale) && std::abs(food.reward_scale) <= 1e3, "food.reward_scale",
              food.reward_scale, "must be in [-1000, 1000]");
  check_field(obs_min_agents >= 0 && obs_min_agents <= 32, "obs_min_agents", obs_min_agents,
              "must be in [0, 32]");
  check_field(obs_min_ramps >= 0 && obs_min_ramps <= 16, "obs_min_ramps", obs_min_ramps,
              "must be in [0, 16]");
  check_field(restrict_rect[0] < restrict_rect[2], "restrict_rect x_min", restrict_rect[0],
              "must be < x_max");
  check_field(restrict_rect[1] < restrict_rect[3], "restrict_rect y_min", restrict_rect[1],
              "must be < y_max");
}

void Task::validate(const physics::WorldConfig& world, const GameRules& /*rules*/) const {
  refuse_sites(world);
  refuse_counting_layout(world);
}

void Task::require_agent_zero(const physics::WorldConfig& world) {
  physics::check_field(world.scene.hiders.min >= 1, "hiders.min", world.scene.hiders.min,
                       "must be >= 1 in a transfer task (agent 0 does the task)");
}

void Task::refuse_sites(const physics::WorldConfig& world) {
  physics::check_field(world.scene.sites.max == 0, "sites.max", world.scene.sites.max,
                       "must be 0 outside the blueprint task (construction sites are its rules')");
}

void Task::refuse_counting_layout(const physics::WorldConfig& world) {
  physics::check_field(world.scene.layout != physics::Layout::kCounting, "scene.layout",
                       int(world.scene.layout),
                       "the counting layout goes with the object-counting task, and only with it");
}

void Task::refuse_food(const physics::WorldConfig& world) {
  physics::check_field(world.scene.food.max == 0, "food.max", world.scene.food.max,
                       "must be 0 in a transfer task (food is a variant of hide-and-seek)");
}

void SingleAgentTask::validate(const physics::WorldConfig& world, const GameRules& rules) const {
  require_agent_zero(world);
  Task::validate(world, rules);
  refuse_food(world);
}

BatchConfig lone_hider_scene(const Task& task, int horizon) {
  BatchConfig c;
  physics::SceneConfig& s = c.world.scene;
  s = physics::SceneConfig::empty();
  s.hiders = {1, 1};
  s.seekers = {0, 0};
  s.boxes = {1, 1};
  s.elongated = {0, 0};
  s.ramps = {0, 0};
  c.world.horizon = horizon;
  c.world.prep_fraction = 0.0;
  c.world.lock_ramps = false;
  c.rules.task = &task;
  return c;
}

BatchConfig transfer_scene(const Task& task, int horizon) {
  BatchConfig c = lone_hider_scene(task, horizon);
  c.rules.obs_min_agents = 2;
  c.rules.obs_min_ramps = 1;
  return c;
}

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
    if (!absorbed && a < n && out_of_bounds(ref.config.rules, pos + 3 * a)) reward[a] = kOutOfBoundsReward;
    if (a >= n) reward[a] = 0.0f;
  }
  s.episode_return[size_t(env) * 2] += reward[0];
  s.done[env] = ref.world.done() ? 1 : 0;
}

}  // namespace hns::batch
