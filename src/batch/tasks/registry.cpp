// Which task plays which game: one row per physics::WorldConfig::Task value. A scene (a row of the scene
// registry batch::kScenes) names its preset, the preset its WorldConfig::Task, and this switch the Task.
// There is no default: a WorldConfig::Task value without a row here does not compile (the warning is an error
// in this file), and a value outside the enum is refused.
#include <stdexcept>
#include <string>

#include "batch/tasks/task.hpp"

#pragma GCC diagnostic error "-Wswitch"

namespace hns::batch {

// Each defined in its game's file.
const Task& hide_and_seek_task();
const Task& lock_task();
const Task& shelter_task();
const Task& blueprint_task();
const Task& object_counting_task();

const Task& task_for(physics::WorldConfig::Task task) {
  using Game = physics::WorldConfig::Task;
  switch (task) {
    case Game::kHideAndSeek:
      return hide_and_seek_task();
    case Game::kLockBox:
    case Game::kLockReturn:
    case Game::kSequentialLock:
      return lock_task();
    case Game::kShelter:
      return shelter_task();
    case Game::kBlueprint:
      return blueprint_task();
    case Game::kCounting:
      return object_counting_task();
  }
  throw std::logic_error("batch::task_for: no task plays WorldConfig::Task " + std::to_string(int(task)));
}

}  // namespace hns::batch
