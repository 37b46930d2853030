// The registry of scenes: every named game a batch can play (its world and its rules), with its description
// and family, and per-run count overrides; shared by the CLI, Python, the benchmarks and the docs test.
//
// A scene is one row of kScenes below, whose preset function is defined in its game's file in tasks/
// (tasks/task.hpp says how to add a game).
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "batch/batch_sim.hpp"

namespace hns::batch {

// What a scene is for; decides which commands take it (hns eval --tasks takes kTransfer, hns counting
// kProbe).
enum class SceneFamily : uint8_t {
  kHideAndSeek,  // the hide-and-seek game (hns train's main use)
  kFood,         // the paper's food variants of the full game (docs/food.md)
  kTransfer,     // single-agent transfer tasks (docs/transfer.md; hns eval --tasks)
  kProbe,        // a probe of a frozen policy without reward (hns counting)
};
const char* family_name(SceneFamily family);

struct SceneInfo {
  const char* name;     // what --scene, hns.BatchEnv(scene=...) and trajectory headers say
  const char* summary;  // one line, for --help and the docs
  SceneFamily family;
  // The scene's world and rules; the batch's own fields (envs, threads, seed) keep their defaults.
  BatchConfig (*preset)();
};

// The presets, each defined in its game's file (tasks/).
BatchConfig quadrant_scene();         // hide_and_seek.cpp
BatchConfig full_scene();             // hide_and_seek.cpp
BatchConfig empty_scene();            // hide_and_seek.cpp
BatchConfig lockbox_scene();          // lock_tasks.cpp
BatchConfig lock_and_return_scene();  // lock_tasks.cpp
BatchConfig sequential_lock_scene();  // lock_tasks.cpp
BatchConfig shelter_scene();          // shelter.cpp
BatchConfig blueprint_scene();        // blueprint.cpp
BatchConfig object_counting_scene();  // object_counting.cpp
BatchConfig food_scene();             // food.cpp
BatchConfig dynamic_food_scene();     // food.cpp

// Every scene, in the order the CLI and the docs list them. A scene exists exactly when it has a row here.
inline constexpr std::array<SceneInfo, 11> kScenes = {{
    {"quadrant", "a corner room with doors (the paper's quadrant game)", SceneFamily::kHideAndSeek,
     &quadrant_scene},
    {"full", "random rooms (the paper's full game)", SceneFamily::kHideAndSeek, &full_scene},
    {"empty", "the arena without inner walls (short episodes: benches and tests)", SceneFamily::kHideAndSeek,
     &empty_scene},
    {"lockbox", "one agent must reach and lock a cube", SceneFamily::kTransfer, &lockbox_scene},
    {"lock-and-return", "lock the cube in one of 6 rooms, then return to the spawn point",
     SceneFamily::kTransfer, &lock_and_return_scene},
    {"sequential-lock", "lock 4 cubes in index order in 3 door-less rooms", SceneFamily::kTransfer,
     &sequential_lock_scene},
    {"shelter", "hide a cylinder from rays with 8 boxes (build a shelter)", SceneFamily::kTransfer,
     &shelter_scene},
    {"blueprint", "place cubes on 1-4 construction sites", SceneFamily::kTransfer, &blueprint_scene},
    {"object-counting", "a frozen policy watches 6 cubes slide out of view (no reward; hns counting)",
     SceneFamily::kProbe, &object_counting_scene},
    {"food", "the full game with 5 food items in the middle that respawn", SceneFamily::kFood, &food_scene},
    {"dynamic-food", "3 hiders, 2 seekers, 8 elongated boxes, one food item that moves when eaten",
     SceneFamily::kFood, &dynamic_food_scene},
}};

// The scene called `name`, or nullptr.
const SceneInfo* find_scene(std::string_view name);
// The names of every scene (of one family when given), in registry order.
std::vector<std::string> scene_names(std::optional<SceneFamily> family = std::nullopt);
// Those names joined by `separator`.
std::string scene_list(const std::string& separator, std::optional<SceneFamily> family = std::nullopt);

// The batch config of scene `name`: its preset (docs/transfer.md, docs/food.md). Throws
// physics::ConfigError naming the allowed names.
BatchConfig scene_config(const std::string& name);

// Fixed counts that replace what the scene would draw per episode (unset = keep the preset's range).
struct CountOverrides {
  std::optional<int> hiders, seekers, boxes, ramps;
};

// Applies the overrides; with a fixed box count the elongated range is clamped into it.
void apply_overrides(physics::WorldConfig& config, const CountOverrides& counts);

}  // namespace hns::batch
