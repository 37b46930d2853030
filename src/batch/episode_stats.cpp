// Episode statistics (docs/game.md §7, docs/training.md "Stages"): what the preparation phase left (measured
// when it ends and again when the episode ends), the seeking phase's running counts, and the record of a
// finished episode that BatchSim::finished() reports. The geometry behind the stage detectors is in
// stage_stats.cpp.
#include <algorithm>
#include <cmath>

#include "batch/env.hpp"

namespace hns::batch {
namespace {

Footprint box_footprint(const EnvRef& ref, int box) {
  const size_t i = size_t(ref.index) * ref.L.max_boxes + box;
  const BatchState& s = ref.s;
  return Footprint{s.box_pos[3 * i],     s.box_pos[3 * i + 1],     s.box_rot[2 * i],
                   s.box_rot[2 * i + 1], 0.5f * s.box_size[3 * i], 0.5f * s.box_size[3 * i + 1]};
}

}  // namespace

void measure_stats(const EnvRef& ref, float out[kNumPrepStats]) {
  const int env = ref.index;
  const Layout& L = ref.L;
  const BatchState& s = ref.s;
  auto max_move = [](const float* pos, const float* start, const uint8_t* exists, int n) {
    float best = 0.0f;
    for (int i = 0; i < n; ++i) {
      if (exists[i] == 0) continue;
      const float dx = pos[3 * i] - start[3 * i], dy = pos[3 * i + 1] - start[3 * i + 1];
      const float dz = pos[3 * i + 2] - start[3 * i + 2];
      best = std::max(best, std::sqrt(dx * dx + dy * dy + dz * dz));
    }
    return best;
  };
  auto count = [](const uint8_t* flags, int n) {
    int c = 0;
    for (int i = 0; i < n; ++i) c += flags[i];
    return float(c);
  };
  const size_t b = size_t(env) * L.max_boxes, r = size_t(env) * L.max_ramps;
  out[kBoxMove] = max_move(s.box_pos.data() + (3 * b), s.box_pos_start.data() + (3 * b),
                           s.box_exists.data() + b, L.max_boxes);
  out[kBoxLock] = count(s.box_locked.data() + b, L.max_boxes);
  out[kRampMove] = max_move(s.ramp_pos.data() + (3 * r), s.ramp_pos_start.data() + (3 * r),
                            s.ramp_exists.data() + r, L.max_ramps);
  out[kRampLock] = count(s.ramp_locked.data() + r, L.max_ramps);

  // Doors sealed by the locked boxes (stage_stats.hpp), and doors the boxes cover whether locked or not
  // (boxes moved into the doorways). At most kMaxSealBoxes boxes are looked at: far more than any scene the
  // presets build.
  constexpr int kMaxSealBoxes = 32;
  Footprint locked[kMaxSealBoxes], all[kMaxSealBoxes];
  int num_locked = 0, num_all = 0;
  for (int k = 0; k < L.max_boxes && num_all < kMaxSealBoxes; ++k) {
    if (s.box_exists[b + k] == 0) continue;
    all[num_all++] = box_footprint(ref, k);
    if (s.box_locked[b + k] != 0) locked[num_locked++] = all[num_all - 1];
  }
  const physics::Scene& scene = ref.world.scene();
  int sealed = 0, blocked = 0;
  for (const physics::DoorCells& door : scene.doors) {
    const DoorGap gap = door_gap(scene, door);
    sealed += door_sealed(gap, std::span<const Footprint>(locked, size_t(num_locked))) ? 1 : 0;
    blocked += door_sealed(gap, std::span<const Footprint>(all, size_t(num_all))) ? 1 : 0;
  }
  out[kDoorsSealed] = float(sealed);
  out[kDoorsBlocked] = float(blocked);
  bool in_room = false;
  if (scene.layout == physics::Layout::kQuadrant) {
    const Rect room = quadrant_room();
    for (int k = 0; k < L.max_ramps; ++k) {
      const float* p = s.ramp_pos.data() + 3 * (r + k);
      in_room = in_room || (s.ramp_exists[r + k] != 0 && room.contains(p[0], p[1]));
    }
  }
  out[kRampInRoom] = in_room ? 1.0f : 0.0f;
  // The hiders inside the quadrant room (their centres) and the hiders beside a locked box, as fractions of
  // the hiders.
  const bool quadrant = scene.layout == physics::Layout::kQuadrant;
  const Rect room = quadrant_room();
  const std::span<const Footprint> locked_boxes(locked, size_t(num_locked));
  int hiders = 0, inside = 0, screened = 0;
  const size_t ea = size_t(env) * L.max_agents;
  for (int a = 0; a < ref.world.num_agents(); ++a) {
    if (s.agent_hider[ea + a] == 0) continue;
    const float* p = s.agent_pos.data() + 3 * (ea + a);
    ++hiders;
    inside += quadrant && room.contains(p[0], p[1]) ? 1 : 0;
    screened += hider_screened(locked_boxes, p[0], p[1], p[2]) ? 1 : 0;
  }
  out[kHidersInRoom] = hiders > 0 ? float(inside) / float(hiders) : 0.0f;
  out[kHidersScreened] = hiders > 0 ? float(screened) / float(hiders) : 0.0f;
}

// The seeking phase's running statistics (stat_run), from this step's mirror and vision.
void track_seeking(EnvRef& ref, bool any_seen) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const physics::World& world = ref.world;
  const int n = world.num_agents(), A = L.max_agents;
  float* run = s.stat_run.data() + size_t(env) * Layout::kRunStats;
  const size_t ea = size_t(env) * A;
  const float* pos = s.agent_pos.data() + 3 * ea;
  const float* vel = s.agent_vel.data() + 3 * ea;
  const uint8_t* hider = s.agent_hider.data() + ea;
  const uint8_t* vis = s.vis_agents.data() + ea * A;
  run[kSeekSteps] += 1.0f;
  run[kSeenSteps] += any_seen ? 1.0f : 0.0f;

  // Ramps against the interior walls (the 0.5 m ones; outer walls are 4 m high).
  const physics::Scene& scene = world.scene();
  for (int r = 0; r < world.num_ramps(); ++r) {
    const size_t i = size_t(env) * L.max_ramps + r;
    const Footprint ramp{
        s.ramp_pos[3 * i],     s.ramp_pos[3 * i + 1],           s.ramp_rot[2 * i],
        s.ramp_rot[2 * i + 1], float(0.5 * physics::kRampSize), float(0.5 * physics::kRampSize)};
    for (const physics::StaticBox& w : scene.wall_boxes) {
      if (2.0 * w.hz > physics::kInteriorWallHeight + 1e-6) continue;
      run[kRampWallDist] = std::min(run[kRampWallDist], footprint_distance(ramp, footprint_of(w)));
    }
  }

  bool surfing = false;
  for (int sk = 0; sk < n; ++sk) {
    if (hider[sk] != 0) continue;
    const float* p = pos + 3 * sk;
    // Approach: the seeker's horizontal velocity towards its nearest hider.
    int nearest = -1;
    float best = 0.0f;
    bool sees_hider = false;
    for (int h = 0; h < n; ++h) {
      if (hider[h] == 0) continue;
      sees_hider = sees_hider || vis[sk * A + h] != 0;
      const float d = std::hypot(pos[3 * h] - p[0], pos[3 * h + 1] - p[1]);
      if (nearest < 0 || d < best) nearest = h, best = d;
    }
    if (nearest >= 0 && best > 1e-6f) {
      const float* q = pos + 3 * nearest;
      run[kApproachSum] += (vel[3 * sk] * (q[0] - p[0]) + vel[3 * sk + 1] * (q[1] - p[1])) / best;
      run[kApproachCount] += 1.0f;
    }
    if (p[2] > kHighAgentZ) {
      run[kSeekerHigh] = 1.0f;
      if (sees_hider) run[kHighSeen] = 1.0f;
    }
    // Surfing: standing on a box that slides.
    for (int k = 0; k < world.num_boxes() && !surfing; ++k) {
      const size_t i = size_t(env) * L.max_boxes + k;
      const float* v = s.box_vel.data() + 3 * i;
      if (std::hypot(v[0], v[1]) < kSurfSpeed) continue;
      const float top = s.box_pos[3 * i + 2] + 0.5f * s.box_size[3 * i + 2];
      surfing = stands_on(box_footprint(ref, k), top, p[0], p[1], p[2]);
    }
  }
  run[kSurfCount] += surfing ? 1.0f : 0.0f;
}

void record_episode(const EnvRef& ref, bool discarded, EpisodeStats& st) {
  const int env = ref.index;
  const BatchState& s = ref.s;
  const float* prep = s.stat_prep.data() + size_t(env) * Layout::kPrepStats;
  const float* run = s.stat_run.data() + size_t(env) * Layout::kRunStats;
  float end[Layout::kPrepStats];
  measure_stats(ref, end);
  st.env = env;
  st.episode = s.episode[env];
  st.length = ref.world.step_count();
  st.discarded = discarded;
  st.hider_return = s.episode_return[size_t(env) * 2];
  st.seeker_return = s.episode_return[size_t(env) * 2 + 1];
  st.max_box_move_prep = prep[kBoxMove];
  st.num_box_lock_prep = prep[kBoxLock];
  st.max_ramp_move_prep = prep[kRampMove];
  st.num_ramp_lock_prep = prep[kRampLock];
  st.max_box_move = end[kBoxMove];
  st.num_box_lock = end[kBoxLock];
  st.max_ramp_move = end[kRampMove];
  st.num_ramp_lock = end[kRampLock];
  st.num_doors = float(ref.world.scene().doors.size());
  st.num_door_sealed_prep = prep[kDoorsSealed];
  st.num_door_sealed = end[kDoorsSealed];
  st.hider_seen_frac = run[kSeekSteps] > 0 ? run[kSeenSteps] / run[kSeekSteps] : 0.0f;
  st.seeker_approach = run[kApproachCount] > 0 ? run[kApproachSum] / run[kApproachCount] : 0.0f;
  st.ramp_wall_dist = run[kRampWallDist];
  st.seeker_high_seen = run[kHighSeen];
  st.seeker_high = run[kSeekerHigh];
  st.ramp_in_room_prep = prep[kRampInRoom];
  st.num_door_blocked_prep = prep[kDoorsBlocked];
  st.hiders_in_room_prep = prep[kHidersInRoom];
  st.hiders_screened_prep = prep[kHidersScreened];
  st.box_surf = run[kSurfCount] >= float(kSurfSteps) ? 1.0f : 0.0f;
  st.food_eaten = run[kFoodEaten];
  st.max_agent_move = 0.0f;
  for (int a = 0; a < ref.world.num_agents(); ++a) {
    const size_t i = (size_t(env) * ref.L.max_agents + a) * 3;
    const float dx = s.agent_pos[i] - s.agent_pos_start[i],
                dy = s.agent_pos[i + 1] - s.agent_pos_start[i + 1];
    const float dz = s.agent_pos[i + 2] - s.agent_pos_start[i + 2];
    st.max_agent_move = std::max(st.max_agent_move, std::sqrt(dx * dx + dy * dy + dz * dz));
  }
}

}  // namespace hns::batch
