// The box-locking tasks (docs/game.md §9.2): a lone hider (agent 0) in the empty arena or in rooms must lock
// the boxes. lockbox: one cube, the nearest unlocked box is the target; lock-and-return: the cube in one of 6
// rooms, then back to the spawn point; sequential-lock: 4 cubes in 3 door-less rooms, locked in index order
// (the world itself refuses a lock out of order: WorldConfig::lock_in_order). One class plays the three, an
// object of it per task with its mode. The reward is dense, shaped by the distance to the current target
// (task_target, task_dist in the batch state). The three scenes' presets are at the end.
#include <algorithm>
#include <cmath>

#include "batch/scenes.hpp"
#include "batch/tasks/task.hpp"

namespace hns::batch {
namespace {

// Which box-locking task: lockbox, lock-and-return or sequential-lock.
enum class LockMode : uint8_t { kLock, kLockReturn, kLockInOrder };

// The target of agent 0 (docs/game.md §9.2): the nearest unlocked box, or in kLockInOrder the first unlocked
// one in index order; once every box is locked, the spawn point in kLockReturn (kTargetSpawn) and none
// otherwise (kTargetNone). task_dist: the 2-D distance to it.
void lockbox_retarget(EnvRef& ref, LockMode mode) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const bool in_order = mode == LockMode::kLockInOrder;
  const float* agent = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
  int best = kTargetNone;
  float best_d = 0.0f;
  for (int b = 0; b < L.max_boxes; ++b) {
    const size_t i = size_t(env) * L.max_boxes + b;
    if (s.box_exists[i] == 0 || s.box_locked[i] != 0) continue;
    const float d = std::hypot(s.box_pos[3 * i] - agent[0], s.box_pos[3 * i + 1] - agent[1]);
    if (best < 0 || d < best_d) best = b, best_d = d;
    if (in_order) break;
  }
  if (best == kTargetNone && mode == LockMode::kLockReturn) {
    const float* spawn = s.task_spawn.data() + size_t(env) * 2;
    best = kTargetSpawn;
    best_d = std::hypot(spawn[0] - agent[0], spawn[1] - agent[1]);
  }
  s.task_target[env] = best;
  s.task_dist[env] = best_d;
}

// The reward (docs/game.md §9.2), the original's constants.
constexpr double kLockReward = 5.0;         // per newly locked box
constexpr double kUnlockPenalty = 5.0;      // per newly unlocked box
constexpr double kShapedRewardScale = 0.5;  // per m agent 0 gets closer to its target (2-D)
constexpr double kSuccessReward = 1.0;      // every step the task is complete
constexpr double kReturnThreshold = 0.1;    // lock-and-return: m (2-D) from the spawn that counts as returned

// docs/game.md §9.2 for agent 0 (every agent of the env gets the same reward): +kLockReward per newly locked
// box, -kUnlockPenalty per newly unlocked one; kShapedRewardScale x the decrease of the 2-D distance to the
// target, +scale x the old distance when the target box gets locked, -scale x the new target's distance when
// a box gets unlocked; +kSuccessReward every step the task is complete: all boxes locked (and in kLockReturn
// agent 0 within kReturnThreshold of its spawn).
void lockbox_rewards(EnvRef& ref, LockMode mode, float* reward) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const uint8_t* locked = s.box_locked.data() + size_t(env) * L.max_boxes;
  uint8_t* before = s.task_locked.data() + size_t(env) * L.max_boxes;
  int newly_locked = 0, newly_unlocked = 0;
  for (int b = 0; b < L.max_boxes; ++b) {
    newly_locked += locked[b] != 0 && before[b] == 0;
    newly_unlocked += locked[b] == 0 && before[b] != 0;
    before[b] = locked[b];
  }
  double r = kLockReward * newly_locked - kUnlockPenalty * newly_unlocked;
  const int target = s.task_target[env];
  const double old_dist = s.task_dist[env];
  if (target >= 0 && locked[target] != 0) {
    r += kShapedRewardScale * old_dist;
    lockbox_retarget(ref, mode);
  } else if (newly_unlocked > 0) {
    lockbox_retarget(ref, mode);
    r -= kShapedRewardScale * s.task_dist[env];
  } else if (target != kTargetNone) {
    lockbox_retarget(ref, mode);
    r += kShapedRewardScale * (old_dist - s.task_dist[env]);
  }
  const int now = s.task_target[env];
  if (now == kTargetNone || (now == kTargetSpawn && s.task_dist[env] <= kReturnThreshold)) {
    r += kSuccessReward;
  }
  std::fill_n(reward, L.max_agents, float(r));
}

class LockTask final : public SingleAgentTask {
 public:
  explicit LockTask(LockMode mode) : mode_(mode) {}
  // The world's rule agrees with the target: locks out of order are refused exactly in sequential-lock.
  void validate(const physics::WorldConfig& world, const GameRules& rules) const override {
    SingleAgentTask::validate(world, rules);
    const bool in_order = mode_ == LockMode::kLockInOrder;
    physics::check_field(world.lock_in_order == in_order, "lock_in_order", world.lock_in_order,
                         in_order
                             ? "must be 1 in the sequential-lock task (its boxes are locked in order)"
                             : "must be 0 in the lockbox and lock-and-return tasks (any box may be locked)");
  }
  // The spawn point (lock-and-return's last target) and the first target, from the episode's first mirror.
  void episode_started(EnvRef& ref) const override {
    const int env = ref.index;
    const Layout& L = ref.L;
    BatchState& s = ref.s;
    std::copy_n(s.box_locked.data() + size_t(env) * L.max_boxes, L.max_boxes,
                s.task_locked.data() + size_t(env) * L.max_boxes);
    const float* agent = s.agent_pos.data() + size_t(env) * L.max_agents * 3;
    s.task_spawn[size_t(env) * 2] = agent[0];
    s.task_spawn[size_t(env) * 2 + 1] = agent[1];
    lockbox_retarget(ref, mode_);
  }

 protected:
  void reward(EnvRef& ref, float* reward) const override { lockbox_rewards(ref, mode_, reward); }

 private:
  LockMode mode_;
};

// The task of each mode, built on first use.
const Task& lock_task(LockMode mode) {
  static const LockTask lock(LockMode::kLock), lock_return(LockMode::kLockReturn),
      in_order(LockMode::kLockInOrder);
  return mode == LockMode::kLock ? lock : mode == LockMode::kLockReturn ? lock_return : in_order;
}

}  // namespace

// One hider and one cube in the empty room, horizon 60.
BatchConfig lockbox_scene() {
  return lone_hider_scene(lock_task(LockMode::kLock), 60);
}

// docs/game.md §9.2: lock the box in one of 6 random rooms and return to the spawn (horizon 120).
BatchConfig lock_and_return_scene() {
  BatchConfig c = transfer_scene(lock_task(LockMode::kLockReturn), 120);
  physics::SceneConfig& s = c.world.scene;
  s.layout = physics::Layout::kRandomWalls;
  s.rooms = {6, 6};
  s.prob_outside_walls = 1.0;
  s.door_size = 2;
  return c;
}

// docs/game.md §9.2: lock 4 boxes in order in the 3 door-less var_tri rooms, one lockable ramp per room
// (horizon 120).
BatchConfig sequential_lock_scene() {
  BatchConfig c = transfer_scene(lock_task(LockMode::kLockInOrder), 120);
  physics::SceneConfig& s = c.world.scene;
  s.layout = physics::Layout::kVarTri;
  s.boxes = {4, 4};
  s.ramps = {3, 3};
  c.world.lock_ramps = true;
  c.world.lock_in_order = true;
  return c;
}

}  // namespace hns::batch
