// The task registry (src/batch/tasks/registry.cpp): every scene of the scene registry batch::kScenes is
// played by a task of the right kind; a WorldConfig::Task value without a task is refused; a game or a
// single-agent task without a reward cannot exist (there is no default reward: a new task that forgot its
// rules once silently got shelter's); construction sites are refused outside blueprint, the one task whose
// rules read them.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <type_traits>

#include "batch/scenes.hpp"
#include "batch/tasks/task.hpp"

namespace hns::batch {
namespace {

// A game and a single-agent task that leave out their reward are abstract: no object of either can be made,
// so registering one (registry.cpp returns an object of each task) does not compile.
struct GameWithoutReward : Task {
  void observe(EnvRef& /*env*/) const override {}
};
struct TaskWithoutReward : SingleAgentTask {
  void start_episode(EnvRef& /*env*/, uint64_t /*episode*/) const override {}
};
static_assert(std::is_abstract_v<GameWithoutReward>);
static_assert(std::is_abstract_v<TaskWithoutReward>);
static_assert(std::is_abstract_v<Task> && std::is_abstract_v<SingleAgentTask>);

TEST(TaskRegistry, EveryScenePlaysATaskOfItsKind) {
  for (const SceneInfo& scene : kScenes) {
    SCOPED_TRACE(scene.name);
    const physics::WorldConfig w = scene_config(scene.name).world;
    const Task& task = task_for(w.task);
    // Hide-and-seek and its food variants are the team game; every other scene is a single-agent task.
    EXPECT_EQ(dynamic_cast<const SingleAgentTask*>(&task) != nullptr, w.is_transfer_task());
    EXPECT_EQ(task.scripted(), w.task == physics::WorldConfig::Task::kCounting);
    // docs/game.md §4.3, §9: shelter, blueprint and object counting observe a constant 0 as the hider bit.
    using Game = physics::WorldConfig::Task;
    const bool constant = w.task == Game::kShelter || w.task == Game::kBlueprint || w.task == Game::kCounting;
    EXPECT_EQ(task.hider_observation(), constant ? 0 : -1);
  }
}

TEST(TaskRegistry, RefusesAGameWithoutATask) {
  try {
    (void)task_for(static_cast<physics::WorldConfig::Task>(200));
    ADD_FAILURE() << "no exception";
  } catch (const std::logic_error& e) {
    EXPECT_NE(std::string(e.what()).find("no task plays WorldConfig::Task 200"), std::string::npos)
        << e.what();
  }
}

TEST(TaskRegistry, ConstructionSitesOnlyInBlueprint) {
  physics::WorldConfig c = physics::WorldConfig::lockbox();
  c.scene.sites = {1, 1};
  try {
    c.validate();
    ADD_FAILURE() << "no exception";
  } catch (const physics::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("sites.max = 1 is invalid"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(physics::WorldConfig::blueprint().validate());
}

}  // namespace
}  // namespace hns::batch
