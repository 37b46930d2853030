// The scene registry's lookups (scenes.hpp); the rows' presets are in their games' files (tasks/).
#include "batch/scenes.hpp"

#include <algorithm>

namespace hns::batch {

const char* family_name(SceneFamily family) {
  switch (family) {
    case SceneFamily::kHideAndSeek:
      return "hide-and-seek";
    case SceneFamily::kFood:
      return "food";
    case SceneFamily::kTransfer:
      return "transfer";
    case SceneFamily::kProbe:
      return "probe";
  }
  return "?";
}

const SceneInfo* find_scene(std::string_view name) {
  for (const SceneInfo& s : kScenes)
    if (name == s.name) return &s;
  return nullptr;
}

std::vector<std::string> scene_names(std::optional<SceneFamily> family) {
  std::vector<std::string> names;
  for (const SceneInfo& s : kScenes)
    if (!family || s.family == *family) names.emplace_back(s.name);
  return names;
}

std::string scene_list(const std::string& separator, std::optional<SceneFamily> family) {
  std::string list;
  for (const std::string& n : scene_names(family)) list += (list.empty() ? "" : separator) + n;
  return list;
}

BatchConfig scene_config(const std::string& name) {
  if (const SceneInfo* s = find_scene(name)) return s->preset();
  throw physics::ConfigError("scene = '" + name + "' is invalid: must be one of " + scene_list(", "));
}

void apply_overrides(physics::WorldConfig& config, const CountOverrides& counts) {
  physics::SceneConfig& s = config.scene;
  if (counts.hiders) s.hiders = {*counts.hiders, *counts.hiders};
  if (counts.seekers) s.seekers = {*counts.seekers, *counts.seekers};
  if (counts.ramps) s.ramps = {*counts.ramps, *counts.ramps};
  if (counts.boxes) {
    s.boxes = {*counts.boxes, *counts.boxes};
    s.elongated.max = std::min(s.elongated.max, *counts.boxes);
    s.elongated.min = std::min(s.elongated.min, s.elongated.max);
  }
}

}  // namespace hns::batch
