// The food variants of hide-and-seek (docs/game.md §5.4) on staged scenes, one test per eating rule: a hider
// eats what it saw within reach; not out of reach, not what it did not see, never a seeker, not while a hider
// is seen (unless eat_when_caught), not in the preparation phase; the last units are shared; an eaten-up item
// comes back after respawn_steps (dynamic food: elsewhere in its square); selfish and joint_mean rewards; the
// placement of the paper's five clustered items.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "batch/batch_sim.hpp"
#include "batch/scenes.hpp"

namespace hns::batch {
namespace {

using physics::Scene;
using physics::Spawn;

Spawn agent_at(double x, double y) {
  return Spawn{x, y, physics::kAgentRadius, 0.3, 0.3, 0.3};
}
Spawn food_at(double x, double y) {
  const double s = physics::kFoodSize;
  return Spawn{x, y, 0.5 * s, s, s, s};
}

// Hiders, then seekers, and food items, no walls. Agents spawn facing -y.
Scene food_scene(std::vector<Spawn> hiders, std::vector<Spawn> seekers, std::vector<Spawn> food) {
  Scene s;
  s.num_hiders = int(hiders.size());
  s.num_seekers = int(seekers.size());
  s.agents = hiders;
  s.agents.insert(s.agents.end(), seekers.begin(), seekers.end());
  s.food = std::move(food);
  return s;
}

// The "food" preset without its preparation phase (unless asked), one env.
BatchConfig food_config(double prep_fraction = 0.0, const char* scene = "food") {
  BatchConfig c = scene_config(scene);
  c.world.prep_fraction = prep_fraction;
  c.num_envs = 1;
  return c;
}

// One idle step of the staged scene; returns the sim for inspection.
struct Staged {
  explicit Staged(const BatchConfig& c, const Scene& scene) : sim(c) {
    sim.load_scene(0, scene);
    idle.resize(size_t(sim.layout().max_agents));
  }
  void step() { sim.step(idle); }
  const BatchState& s() const { return sim.state(); }
  BatchSim sim;
  std::vector<AgentAction> idle;
};

// A hider 0.3 m north of an item (facing it, 0.32 m apart in 3-D) and alone: it eats one unit a step, and
// its reward is the game's +1 plus the unit (joint_mean over one hider).
TEST(Food, AHiderThatSeesAnItemWithinReachEatsOneUnitAStep) {
  Staged t(food_config(), food_scene({agent_at(3.0, 3.3)}, {}, {food_at(3.0, 3.0)}));
  EXPECT_EQ(t.s().food_eat_ok[0], 1);
  t.step();
  EXPECT_FLOAT_EQ(t.s().food_eaten[0], 1.0f);
  EXPECT_FLOAT_EQ(t.s().food_health[0], 39.0f);
  EXPECT_FLOAT_EQ(t.s().reward[0], 2.0f);
  // Observed as position and health, through vision.
  const Layout& L = t.sim.layout();
  ASSERT_EQ(L.site_features, Layout::kFoodFeatures);
  EXPECT_FLOAT_EQ(t.s().obs_sites[0], 3.0f);
  EXPECT_FLOAT_EQ(t.s().obs_sites[3], 39.0f);
  EXPECT_EQ(t.s().mask_sites[0], 1);
  EXPECT_EQ(t.s().value_mask_sites[0], 1);
  t.step();
  EXPECT_FLOAT_EQ(t.s().food_health[0], 38.0f);
}

TEST(Food, AnItemOutOfReachIsNotEaten) {
  Staged t(food_config(), food_scene({agent_at(3.0, 3.6)}, {}, {food_at(3.0, 3.0)}));  // 0.61 m in 3-D
  EXPECT_EQ(t.s().food_eat_ok[0], 1) << "seen";
  t.step();
  EXPECT_EQ(t.s().food_eaten[0], 0.0f);
  EXPECT_FLOAT_EQ(t.s().food_health[0], 40.0f);
  EXPECT_FLOAT_EQ(t.s().reward[0], 1.0f);
}

TEST(Food, AnItemTheHiderDoesNotSeeIsNotEaten) {
  Staged t(food_config(), food_scene({agent_at(3.0, 2.7)}, {}, {food_at(3.0, 3.0)}));  // behind it
  EXPECT_EQ(t.s().vis_food[0], 0);
  EXPECT_EQ(t.s().food_eat_ok[0], 0);
  EXPECT_EQ(t.s().mask_sites[0], 0);
  EXPECT_EQ(t.s().value_mask_sites[0], 1);
  t.step();
  EXPECT_EQ(t.s().food_eaten[0], 0.0f);
  EXPECT_FLOAT_EQ(t.s().food_health[0], 40.0f);
}

TEST(Food, SeekersNeverEat) {
  // The seeker stands over the item, facing it; the hider is far away and unseen.
  Staged t(food_config(), food_scene({agent_at(1.0, 1.0)}, {agent_at(3.0, 3.3)}, {food_at(3.0, 3.0)}));
  EXPECT_EQ(t.s().vis_food[t.sim.layout().max_food], 1) << "the seeker sees it";
  t.step();
  EXPECT_EQ(t.s().food_eaten[1], 0.0f);
  EXPECT_FLOAT_EQ(t.s().food_health[0], 40.0f);
}

// A seeker 1 m north of the hider, both facing -y, sees it: no hider eats then, unless eat_when_caught.
TEST(Food, NoHiderEatsWhileAHiderIsSeen) {
  const Scene scene = food_scene({agent_at(3.0, 3.3)}, {agent_at(3.0, 4.3)}, {food_at(3.0, 3.0)});
  Staged t(food_config(), scene);
  ASSERT_EQ(t.s().vis_agents[1 * t.sim.layout().max_agents + 0], 1) << "the seeker sees the hider";
  EXPECT_EQ(t.s().food_eat_ok[0], 0);
  t.step();
  EXPECT_EQ(t.s().food_eaten[0], 0.0f);
  EXPECT_FLOAT_EQ(t.s().reward[0], -1.0f);

  BatchConfig caught = food_config();
  caught.rules.food.eat_when_caught = true;
  Staged u(caught, scene);
  u.step();
  EXPECT_FLOAT_EQ(u.s().food_eaten[0], 1.0f);
  EXPECT_FLOAT_EQ(u.s().reward[0], 0.0f);  // -1 seen, +1 eaten
}

TEST(Food, NoEatingInThePreparationPhase) {
  Staged t(food_config(0.4), food_scene({agent_at(3.0, 3.3)}, {}, {food_at(3.0, 3.0)}));
  const int prep = t.sim.config().world.prep_steps();
  ASSERT_GT(prep, 2);
  for (int k = 1; k <= prep; ++k) {
    t.step();
    ASSERT_EQ(t.s().food_eaten[0], 0.0f) << "step " << k;
  }
  t.step();  // the first step after the preparation phase
  EXPECT_FLOAT_EQ(t.s().food_eaten[0], 1.0f);
  EXPECT_FLOAT_EQ(t.s().food_health[0], 39.0f);
}

// Two hiders at an item with one unit left share it; with selfish rewards each gets what it ate, with
// joint_mean every hider gets the hiders' mean (a third hider that ate nothing included).
TEST(Food, HidersShareTheLastUnitAndTheRewardFollowsTheMode) {
  BatchConfig c = food_config();
  c.rules.food.max_health = 1.0;
  const Scene scene =
      food_scene({agent_at(2.8, 3.25), agent_at(3.2, 3.25), agent_at(1.0, 1.0)}, {}, {food_at(3.0, 3.0)});
  Staged joint(c, scene);
  ASSERT_EQ(joint.s().food_eat_ok[0], 1);
  ASSERT_EQ(joint.s().food_eat_ok[size_t(joint.sim.layout().max_food)], 1);
  joint.step();
  EXPECT_FLOAT_EQ(joint.s().food_eaten[0], 0.5f);
  EXPECT_FLOAT_EQ(joint.s().food_eaten[1], 0.5f);
  EXPECT_EQ(joint.s().food_eaten[2], 0.0f);
  EXPECT_EQ(joint.s().food_health[0], 0.0f);
  for (int a = 0; a < 3; ++a) EXPECT_FLOAT_EQ(joint.s().reward[a], 1.0f + 1.0f / 3.0f) << a;

  c.rules.food.joint_mean = false;
  Staged selfish(c, scene);
  selfish.step();
  EXPECT_FLOAT_EQ(selfish.s().reward[0], 1.5f);
  EXPECT_FLOAT_EQ(selfish.s().reward[1], 1.5f);
  EXPECT_FLOAT_EQ(selfish.s().reward[2], 1.0f);
}

// An item eaten up at step 1 stays empty for respawn_steps = 5 steps (1..5), is full again after step 6, and
// the hider standing at it eats again at step 7. The episode's statistic counts every unit.
TEST(Food, AnEatenUpItemComesBackAfterRespawnSteps) {
  BatchConfig c = food_config();
  c.rules.food.max_health = 1.0;
  Staged t(c, food_scene({agent_at(3.0, 3.3)}, {}, {food_at(3.0, 3.0)}));
  const float want[7] = {0, 0, 0, 0, 0, 1, 0};
  float eaten = 0;
  for (int k = 0; k < 7; ++k) {
    t.step();
    EXPECT_EQ(t.s().food_health[0], want[k]) << "after step " << k + 1;
    eaten += t.s().food_eaten[0];
  }
  EXPECT_EQ(eaten, 2.0f);
  EXPECT_EQ(t.s().stat_run[kFoodEaten], 2.0f);
}

// Dynamic food: one unit, back one step after it is eaten, at a new spot of the centred square of 1/5 the
// arena's side (cells 11 .. 16: centres from 2.25 to 3.35 m).
TEST(Food, DynamicFoodMovesToANewSpotOfItsSquareWhenEaten) {
  BatchConfig c = food_config(0.0, "dynamic-food");
  Staged t(c, food_scene({agent_at(3.0, 3.3)}, {}, {food_at(3.0, 3.0)}));
  t.step();
  EXPECT_FLOAT_EQ(t.s().food_eaten[0], 1.0f);
  EXPECT_EQ(t.s().food_health[0], 0.0f);
  t.step();
  EXPECT_EQ(t.s().food_health[0], 1.0f);
  // The step's vision looked at the old spot: the moved item is unseen (masked, not edible) until the next.
  EXPECT_EQ(t.s().vis_food[0], 0);
  EXPECT_EQ(t.s().mask_sites[0], 0);
  EXPECT_EQ(t.s().food_eat_ok[0], 0);
  const float x = t.s().food_pos[0], y = t.s().food_pos[1];
  EXPECT_FALSE(x == 3.0f && y == 3.0f);
  for (float v : {x, y}) {
    EXPECT_GE(v, 2.25f - 1e-5f);
    EXPECT_LE(v, 3.35f + 1e-5f);
  }
}

// The paper's food game: five items close together in the centred square of 1/4 the side; the first in cells
// 11 .. 16, the others within 2 cells of it.
TEST(Food, FivePelletsSpawnTogetherInTheCentre) {
  const physics::WorldConfig w = scene_config("food").world;
  for (int seed = 0; seed < 200; ++seed) {
    physics::Rng rng(uint64_t(seed), 0, 0);
    Scene s;
    physics::generate_scene(w.scene, rng, s);
    ASSERT_EQ(s.food.size(), 5u);
    const Spawn& first = s.food[0];
    for (double v : {first.x, first.y}) {
      EXPECT_GE(v, 11 * 0.2 + 0.05 - 1e-9);
      EXPECT_LE(v, 16 * 0.2 + 0.15 + 1e-9);
    }
    for (const Spawn& f : s.food) {
      EXPECT_LE(std::fabs(f.x - first.x), 0.4 + 0.1 + 1e-9);
      EXPECT_LE(std::fabs(f.y - first.y), 0.4 + 0.1 + 1e-9);
      EXPECT_EQ(f.z, 0.05);
    }
  }
}

}  // namespace
}  // namespace hns::batch
