// A scene config's presets, its layout names and its validation (docs/game.md §2.1, §2.6, §14.5); the
// generation itself is in scene.cpp.
#include "physics/scene.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "physics/scene_limits.hpp"

namespace hns::physics {
namespace {

using namespace scene_limits;

// Validation helpers: "field = value is invalid: allowed".
template <typename T>
[[noreturn]] void reject(const std::string& field, T value, const std::string& allowed) {
  std::ostringstream out;
  out << field << " = " << value << " is invalid: " << allowed;
  throw ConfigError(out.str());
}

void check_range(const char* name, const IntRange& r) {
  if (r.min < 0) reject(std::string(name) + ".min", r.min, "must be >= 0");
  if (r.max < r.min) {
    reject(std::string(name) + ".max", r.max,
           "must be >= " + std::string(name) + ".min (" + std::to_string(r.min) + ")");
  }
}

void check_probability(const char* name, double p) {
  if (!(p >= 0.0 && p <= 1.0)) reject(name, p, "must be a probability in [0, 1]");
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
Layout parse_layout(const std::string& name) {
  if (name == "empty") return Layout::kEmpty;
  if (name == "quadrant") return Layout::kQuadrant;
  if (name == "randomwalls") return Layout::kRandomWalls;
  if (name == "var_tri") return Layout::kVarTri;
  if (name == "counting") return Layout::kCounting;
  throw ConfigError("layout = '" + name +
                    "' is invalid: must be one of empty, quadrant, randomwalls, var_tri, counting");
}

const char* layout_name(Layout layout) {
  switch (layout) {
    case Layout::kEmpty:
      return "empty";
    case Layout::kQuadrant:
      return "quadrant";
    case Layout::kRandomWalls:
      return "randomwalls";
    case Layout::kVarTri:
      return "var_tri";
    case Layout::kCounting:
      return "counting";
  }
  return "unknown";
}

// hide_and_seek_quadrant.jsonnet (docs/game.md §2.1): 2 v 2, 2 cubes, 1 ramp, a room with one or two doors.
SceneConfig SceneConfig::quadrant() {
  SceneConfig c;
  c.layout = Layout::kQuadrant;
  c.hiders = {2, 2};
  c.seekers = {2, 2};
  c.boxes = {2, 2};
  c.elongated = {0, 0};
  c.ramps = {1, 1};
  c.p_door_dropout = 0.5;
  c.hider_uniform_placement = true;
  c.together_radius = 0.0;
  return c;
}

// The paper's full game (docs/game.md §14.5): 1-3 v 1-3, 3-9 boxes of which at least 3 elongated, 2 ramps,
// 1-4 random rooms, outer walls kept half of the time, team mates spawn within 0.5 m (3 cells) of their first
// member.
SceneConfig SceneConfig::full() {
  SceneConfig c;
  c.layout = Layout::kRandomWalls;
  c.hiders = {1, 3};
  c.seekers = {1, 3};
  c.boxes = {3, 9};
  c.elongated = {3, 9};
  c.ramps = {2, 2};
  c.rooms = {1, 4};
  c.prob_outside_walls = 0.5;
  c.together_radius = 0.5;
  return c;
}

// The bare arena: outer walls only, quadrant counts, everything placed uniformly.
SceneConfig SceneConfig::empty() {
  SceneConfig c = quadrant();
  c.layout = Layout::kEmpty;
  return c;
}

void SceneConfig::validate() const {
  if (layout != Layout::kEmpty && layout != Layout::kQuadrant && layout != Layout::kRandomWalls &&
      layout != Layout::kVarTri && layout != Layout::kCounting) {
    reject("layout", static_cast<int>(layout),
           "must be one of empty, quadrant, randomwalls, var_tri, counting");
  }
  if (layout == Layout::kCounting) {
    if (hiders.min != 1 || hiders.max != 1 || seekers.max != 0)
      reject("hiders", hiders.max, "the counting layout has exactly one hider and no seeker");
    if (boxes.max > 6 || elongated.max != 0 || ramps.max != 0 || sites.max != 0 || food.max != 0)
      reject("boxes.max", boxes.max, "the counting layout has at most 6 cubes and nothing else");
  }
  check_range("hiders", hiders);
  check_range("seekers", seekers);
  check_range("boxes", boxes);
  check_range("elongated", elongated);
  check_range("ramps", ramps);
  check_range("sites", sites);
  check_range("food", food);
  if (food.max > kMaxFood) reject("food.max", food.max, "must be <= " + std::to_string(kMaxFood));
  if (sites.max > 0 && food.max > 0)
    reject("food.max", food.max, "must be 0 in a scene with construction sites (sites.max > 0)");
  if (!(food_middle >= 0.0 && food_middle < 1.0))
    reject("food_middle", food_middle, "must be in [0, 1) (0: the layout's placement)");
  if (!(food_together_radius >= 0.0 && food_together_radius <= kFloorSize))
    reject("food_together_radius", food_together_radius, "must be in [0, 6] m");
  if (sites.max > kMaxSites) reject("sites.max", sites.max, "must be <= " + std::to_string(kMaxSites));
  // Sums in 64 bits: the fields may hold anything a user typed.
  const int64_t min_agents = int64_t{hiders.min} + seekers.min,
                max_agents = int64_t{hiders.max} + seekers.max;
  if (min_agents < 1) reject("hiders.min + seekers.min", min_agents, "at least one agent is required");
  if (max_agents > kMaxAgents) {
    reject("hiders.max + seekers.max", max_agents, "must be <= " + std::to_string(kMaxAgents));
  }
  if (boxes.max > kMaxBoxes) reject("boxes.max", boxes.max, "must be <= " + std::to_string(kMaxBoxes));
  if (ramps.max > kMaxRamps) reject("ramps.max", ramps.max, "must be <= " + std::to_string(kMaxRamps));
  if (elongated.min > boxes.max) {
    reject("elongated.min", elongated.min, "must be <= boxes.max (" + std::to_string(boxes.max) + ")");
  }
  if (target_diameter_max != 0.0 || target_diameter_min != 0.0) {
    if (!(target_diameter_min >= 0.2 && target_diameter_min <= 4.0))
      reject("target_diameter_min", target_diameter_min, "must be in [0.2, 4] m (or both 0: no cylinder)");
    if (!(target_diameter_max >= target_diameter_min && target_diameter_max <= 4.0))
      reject("target_diameter_max", target_diameter_max, "must be in [target_diameter_min, 4] m");
    if (ramps.max > 0)
      reject("ramps.max", ramps.max, "must be 0 with a shelter cylinder (ODE cannot collide a ramp with it)");
  }
  if (layout == Layout::kRandomWalls) {
    if (rooms.min < 1) reject("rooms.min", rooms.min, "must be >= 1");
    if (rooms.max < rooms.min) {
      reject("rooms.max", rooms.max, "must be >= rooms.min (" + std::to_string(rooms.min) + ")");
    }
    if (rooms.max > kMaxRooms) reject("rooms.max", rooms.max, "must be <= " + std::to_string(kMaxRooms));
  }
  if (door_size < 1 || door_size > kMaxDoorSize) {
    reject("door_size", door_size, "must be in [1, " + std::to_string(kMaxDoorSize) + "] cells");
  }
  check_probability("prob_outside_walls", prob_outside_walls);
  check_probability("p_door_dropout", p_door_dropout);
  if (!(together_radius >= 0.0 && std::isfinite(together_radius))) {
    reject("together_radius", together_radius, "must be finite and >= 0 m");
  }
  if (max_tries_per_object < 1) reject("max_tries_per_object", max_tries_per_object, "must be >= 1");
  if (max_regenerations < 1) reject("max_regenerations", max_regenerations, "must be >= 1");

  // Area: objects never share a grid cell, so counts whose footprints exceed the free cells of the region
  // they are placed in can never be produced. Every box and ramp covers 9 cells, every agent 4.
  const int agent_cells = footprint_cells(2 * kAgentRadius) * footprint_cells(2 * kAgentRadius);
  const int box_cells = footprint_cells(kBoxSize) * footprint_cells(kBoxSize);
  const int ramp_cells = footprint_cells(kRampSize) * footprint_cells(kRampSize);
  if (layout == Layout::kQuadrant) {
    // quadrant_placement covers columns 15..27 and rows 1..12; column 15 is room wall except its door cells.
    const int room_free = (kGridSize - 3 - kQuadrantSize) * (kQuadrantSize - 3) + std::min(door_size, 12);
    const int hiders_in_room = hider_uniform_placement ? 0 : hiders.max;
    const int room_need = box_cells * boxes.max + agent_cells * hiders_in_room;
    if (room_need > room_free) {
      std::ostringstream why;
      why << "too many for the quadrant room (" << room_free << " free cells): ";
      if (box_cells * boxes.max <= room_free) {
        why << "next to " << boxes.max << " boxes at most "
            << (room_free - box_cells * boxes.max) / agent_cells << " hiders of " << agent_cells
            << " cells fit inside it (or set hider_uniform_placement)";
        reject("hiders.max", hiders.max, why.str());
      }
      why << "at most " << room_free / box_cells << " boxes of " << box_cells << " cells fit inside it";
      reject("boxes.max", boxes.max, why.str());
    }
  }
  // Every placement function keeps objects within cells 1..28 on both axes (28 x 28 cells).
  const int arena_free = (kGridSize - 2) * (kGridSize - 2);
  const int arena_need = agent_cells * (hiders.max + seekers.max) + box_cells * boxes.max +
                         ramp_cells * ramps.max + box_cells * sites.max + food.max;
  if (arena_need > arena_free) {
    reject("hiders.max + seekers.max + boxes.max + ramps.max",
           hiders.max + seekers.max + boxes.max + ramps.max,
           "the objects need " + std::to_string(arena_need) + " grid cells but the arena has " +
               std::to_string(arena_free));
  }
}

void SceneConfig::check_placeable() const {
  validate();
  SceneConfig most = *this;
  most.hiders = {hiders.max, hiders.max};
  most.seekers = {seekers.max, seekers.max};
  most.boxes = {boxes.max, boxes.max};
  most.ramps = {ramps.max, ramps.max};
  most.sites = {sites.max, sites.max};
  most.food = {food.max, food.max};
  most.rooms = {rooms.max, rooms.max};
  most.target_diameter_min = target_diameter_max;
  const int elongated_hi = std::min(elongated.max, boxes.max);
  Scene scene;
  for (const int elongated_count : {std::min(elongated.min, elongated_hi), elongated_hi}) {
    most.elongated = {elongated_count, elongated_count};
    Rng rng(0x5CE7E5ULL, uint64_t(elongated_count), 0);
    try {
      generate_scene(most, rng, scene);
    } catch (const std::runtime_error& e) {
      throw ConfigError(std::string("the counts cannot be placed: ") + e.what());
    }
  }
}

}  // namespace hns::physics
