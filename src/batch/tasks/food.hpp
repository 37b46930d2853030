// The food variants' rules (docs/game.md §5.4, docs/food.md), played inside the hide-and-seek game
// (hide_and_seek.cpp calls them where the scene has food): the items' state at the start of an episode, the
// eating after each step with its reward, and the food's observation rows.
#pragma once

#include <cstdint>

#include "batch/env.hpp"

namespace hns::batch {

// The episode's food items at full health; the env's random stream for new spots restarts.
void food_start_episode(EnvRef& env, uint64_t episode);
// After a step: eating, health and respawn; adds each hider's food reward to `reward`.
void food_after_step(EnvRef& env, float* reward, bool prep);
// The food's observation rows and the next step's eating mask (food_eat_ok).
void food_observe(EnvRef& env);

}  // namespace hns::batch
