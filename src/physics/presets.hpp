// Named world presets and per-run count overrides shared by the CLI and the benchmarks.
#pragma once

#include <array>
#include <optional>
#include <string>

#include "physics/world.hpp"

namespace hns::physics {

// Every scene name world_preset() knows, in the order the CLI lists them.
inline constexpr std::array<const char*, 11> kSceneNames = {
    "quadrant", "full",      "empty",           "lockbox", "lock-and-return", "sequential-lock",
    "shelter",  "blueprint", "object-counting", "food",    "dynamic-food"};

// "quadrant" (SPEC §14.5 quadrant game), "full" (the paper's full game on random rooms), "empty", "lockbox"
// (one agent must reach and lock a cube: the box-locking task of SPEC §9.2), and the transfer tasks
// "lock-and-return", "sequential-lock" (SPEC §9.2), "shelter" (§9.3), "blueprint" (§9.1) and
// "object-counting" (the paper's §6),
// docs/transfer.md; and the food variants of the full game "food" and "dynamic-food" (§5.4, docs/food.md).
// Throws ConfigError naming the allowed names.
WorldConfig world_preset(const std::string& name);

// Fixed counts that replace what the scene would draw per episode (unset = keep the preset's range).
struct CountOverrides {
  std::optional<int> hiders, seekers, boxes, ramps;
};

// Applies the overrides; with a fixed box count the elongated range is clamped into it.
void apply_overrides(WorldConfig& config, const CountOverrides& counts);

}  // namespace hns::physics
