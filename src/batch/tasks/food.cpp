// The food variants of the hide-and-seek game (docs/game.md §5.4, docs/food.md): food items the hiders eat
// for reward while no hider is seen; "food" has 5 items close together that respawn, "dynamic-food" one item
// that moves to a new spot when eaten. Settings: GameRules::food (batch/game.hpp); the items' placement is
// the scene's. The two scenes' presets are at the end.
#include "batch/tasks/food.hpp"

#include <algorithm>
#include <cmath>

#include "batch/scenes.hpp"

namespace hns::batch {

void food_start_episode(EnvRef& ref, uint64_t episode) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const physics::Scene& scene = ref.world.scene();
  const int nf = int(scene.food.size());
  for (int f = 0; f < L.max_food; ++f) {
    const size_t i = size_t(env) * L.max_food + f;
    float* p = s.food_pos.data() + i * 3;
    p[0] = f < nf ? float(scene.food[f].x) : 0.0f;
    p[1] = f < nf ? float(scene.food[f].y) : 0.0f;
    p[2] = f < nf ? float(scene.food[f].z) : 0.0f;
    s.food_health[i] = f < nf ? float(ref.config.rules.food.max_health) : 0.0f;
    s.food_respawn[i] = 0;
    s.food_exists[i] = f < nf ? 1 : 0;
  }
  std::fill_n(s.food_eaten.data() + size_t(env) * L.max_agents, L.max_agents, 0.0f);
  ref.rng =
      physics::Rng(ref.config.seed ^ 0xF00DF00DULL, uint64_t(ref.config.first_env) + uint64_t(env), episode);
}

// The food variants (docs/game.md §5.4), after the step: every hider the previous observation let eat an item
// (food_eat_ok) and within eat_radius of it eats 1 unit of it, outside the preparation phase; hiders that
// would together eat more than is left share it. An item eaten up stays at 0 for respawn_steps steps (the
// step it was emptied counts as the first), then its health resets, at a new spot with relocate. Each hider
// gets the units it ate, or the hiders' mean of them (joint_mean), times reward_scale; seekers get nothing.
void food_after_step(EnvRef& ref, float* reward, bool prep) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const FoodConfig& fc = ref.config.rules.food;
  const int n = ref.world.num_agents(), F = L.max_food;
  const size_t ea = size_t(env) * L.max_agents, ef = size_t(env) * F;
  const float* pos = s.agent_pos.data() + ea * 3;
  const uint8_t* hider = s.agent_hider.data() + ea;
  const uint8_t* eat_ok = s.food_eat_ok.data() + ea * F;
  float* eaten = s.food_eaten.data() + ea;
  std::fill_n(eaten, L.max_agents, 0.0f);
  const float reach2 = float(fc.eat_radius * fc.eat_radius);
  float total = 0.0f;
  for (int f = 0; f < F; ++f) {
    const size_t i = ef + size_t(f);
    if (s.food_exists[i] == 0) continue;
    float* p = s.food_pos.data() + i * 3;
    float& health = s.food_health[i];
    auto eats = [&](int a) {
      if (prep || health <= 0.0f || eat_ok[a * F + f] == 0) return false;
      const float dx = pos[3 * a] - p[0], dy = pos[3 * a + 1] - p[1], dz = pos[3 * a + 2] - p[2];
      return dx * dx + dy * dy + dz * dz < reach2;
    };
    int count = 0;
    for (int a = 0; a < n; ++a) count += eats(a) ? 1 : 0;
    if (count > 0) {
      const float share = std::min(1.0f, health / float(count));
      for (int a = 0; a < n; ++a)
        if (eats(a)) eaten[a] += share;
      health = std::max(0.0f, health - share * float(count));
      total += share * float(count);
    }
    int32_t& empty_steps = s.food_respawn[i];
    if (fc.respawn_steps > 0 && empty_steps == fc.respawn_steps) {
      health = float(fc.max_health);
      if (fc.relocate) {
        const auto [x, y] = physics::food_respawn_spot(ref.config.world.scene, ref.rng);
        p[0] = float(x), p[1] = float(y);
        // This step's vision looked at the old spot: the moved item counts as unseen until the next step's
        // vision (masked in this observation, not eaten at the next step).
        for (int a = 0; a < L.max_agents; ++a) s.vis_food[(size_t(env) * L.max_agents + a) * F + f] = 0;
      }
    }
    empty_steps = health <= 0.0f ? empty_steps + 1 : 0;
  }
  s.stat_run[size_t(env) * Layout::kRunStats + kFoodEaten] += total;
  float hider_units = 0.0f;
  int hiders = 0;
  for (int a = 0; a < n; ++a) {
    hider_units += hider[a] != 0 ? eaten[a] : 0.0f;
    hiders += hider[a];
  }
  const float scale = float(fc.reward_scale);
  for (int a = 0; a < n; ++a) {
    if (hider[a] == 0) continue;
    reward[a] += scale * (fc.joint_mean ? hider_units / float(hiders) : eaten[a]);
  }
}

// Food (docs/game.md §5.4): position and health, seen through vision; a hider may eat what it sees while no
// hider is seen (unless eat_when_caught), which the next step's eating reads.
void food_observe(EnvRef& ref) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const int A = L.max_agents, C = L.max_sites, F = L.max_food, SF = L.site_features;
  const int n = ref.world.num_agents();
  const size_t ea = size_t(env) * A;
  float* obs_sites = s.obs_sites.data() + ea * C * SF;
  uint8_t* mask_sites = s.mask_sites.data() + ea * C;
  uint8_t* value_mask_sites = s.value_mask_sites.data() + ea * C;
  uint8_t* eat_ok = s.food_eat_ok.data() + ea * F;
  const uint8_t* hider = s.agent_hider.data() + ea;
  const uint8_t* vis_agents = s.vis_agents.data() + ea * A;
  const uint8_t* vis_food = s.vis_food.data() + ea * F;
  // No hider is seen by a seeker in this observation (the food variants' eating mask).
  bool eat_free = true;
  for (int sk = 0; sk < n && F > 0; ++sk) {
    if (hider[sk] != 0) continue;
    for (int h = 0; h < n; ++h) eat_free = eat_free && !(hider[h] != 0 && vis_agents[sk * A + h] != 0);
  }
  for (int a = 0; a < n; ++a) {
    for (int f = 0; f < F; ++f) {
      const size_t i = size_t(env) * F + f;
      if (s.food_exists[i] == 0) continue;
      float* out = obs_sites + (size_t(a) * C + f) * SF;
      std::copy_n(s.food_pos.data() + 3 * i, 3, out);
      out[3] = s.food_health[i];
      const uint8_t seen = vis_food[a * F + f];
      mask_sites[a * C + f] = seen;
      value_mask_sites[a * C + f] = 1;
      eat_ok[a * F + f] =
          hider[a] != 0 && seen != 0 && (eat_free || ref.config.rules.food.eat_when_caught) ? 1 : 0;
    }
  }
}

// The paper's food variants of the full game (docs/food.md): 5 items of 40 units close together in the
// centred square (food_middle 0.25), respawning 5 steps after they are eaten up ("food"; FoodConfig's
// defaults are the full game's values, docs/game.md §5.4).
BatchConfig food_scene() {
  BatchConfig c = full_scene();
  c.world.scene.food = {5, 5};
  c.world.scene.food_middle = 0.25;
  c.world.scene.food_together_radius = 0.25;
  return c;
}

// One item of 1 unit that moves to a new spot of the centred square (food_middle 0.2; both are cells 11 ..
// 16) when eaten, with 3 hiders, 2 seekers and 8 elongated boxes in an arena without walls ("dynamic-food").
BatchConfig dynamic_food_scene() {
  BatchConfig c = full_scene();
  physics::SceneConfig& s = c.world.scene;
  s.layout = physics::Layout::kRandomWalls;
  s.rooms = {1, 1};
  s.prob_outside_walls = 0.0;  // no walls at all
  s.hiders = {3, 3};
  s.seekers = {2, 2};
  s.boxes = {8, 8};
  s.elongated = {8, 8};
  s.ramps = {0, 0};
  c.rules.obs_min_ramps = 1;  // the hide-and-seek policy's ramp slot, empty
  s.food = {1, 1};
  s.food_middle = 0.2;
  c.rules.food.max_health = 1.0;
  c.rules.food.respawn_steps = 1;
  c.rules.food.relocate = true;
  return c;
}

}  // namespace hns::batch
