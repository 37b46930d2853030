// The caps that SceneConfig::validate enforces and scene generation's fixed-size scratch relies on, and the
// grid footprint of an object; shared by scene.cpp (generation) and scene_config.cpp (validation) only.
#pragma once

#include <cmath>

#include "physics/scene.hpp"

namespace hns::physics::scene_limits {

constexpr int kMaxAgents = 32;
constexpr int kMaxBoxes = 32;
constexpr int kMaxRamps = 16;
constexpr int kMaxSites = 8;
constexpr int kMaxFood = 32;
constexpr int kMaxRooms = 8;
constexpr int kMaxDoorSize = 10;
constexpr int kMaxRoomWalls = kMaxRooms + 3;            // 4 outer walls + rooms - 1 interior walls
constexpr int kMaxEdges = 2 + 2 * (kMaxRoomWalls - 1);  // per side: own endpoints + 2 per other wall

// Cells an object of `size` m covers along one axis: ceil(size / 0.2), robust to 0.3 / 0.2 = 1.4999...
inline int footprint_cells(double size) {
  return static_cast<int>(std::ceil(size / kCellSize - 1e-9));
}

}  // namespace hns::physics::scene_limits
