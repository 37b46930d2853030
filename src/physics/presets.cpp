#include "physics/presets.hpp"

#include <algorithm>

namespace hns::physics {

WorldConfig world_preset(const std::string& name) {
  if (name == "quadrant") return WorldConfig::quadrant();
  if (name == "full") return WorldConfig::full();
  if (name == "empty") return WorldConfig::empty();
  if (name == "lockbox") return WorldConfig::lockbox();
  if (name == "lock-and-return") return WorldConfig::lock_and_return();
  if (name == "sequential-lock") return WorldConfig::sequential_lock();
  if (name == "shelter") return WorldConfig::shelter();
  if (name == "blueprint") return WorldConfig::blueprint();
  if (name == "object-counting") return WorldConfig::object_counting();
  if (name == "food") return WorldConfig::food_game();
  if (name == "dynamic-food") return WorldConfig::dynamic_food_game();
  std::string names;
  for (const char* n : kSceneNames) names += std::string(names.empty() ? "" : ", ") + n;
  throw ConfigError("scene = '" + name + "' is invalid: must be one of " + names);
}

void apply_overrides(WorldConfig& config, const CountOverrides& counts) {
  SceneConfig& s = config.scene;
  if (counts.hiders) s.hiders = {*counts.hiders, *counts.hiders};
  if (counts.seekers) s.seekers = {*counts.seekers, *counts.seekers};
  if (counts.ramps) s.ramps = {*counts.ramps, *counts.ramps};
  if (counts.boxes) {
    s.boxes = {*counts.boxes, *counts.boxes};
    s.elongated.max = std::min(s.elongated.max, *counts.boxes);
    s.elongated.min = std::min(s.elongated.min, s.elongated.max);
  }
}

}  // namespace hns::physics
