#include "ppo/intrinsic.hpp"

#include <algorithm>
#include <cmath>

#include "physics/rng.hpp"
#include "physics/scene.hpp"
#include "ppo/atomic_file.hpp"

namespace hns::ppo {

namespace {

enum Kind { kAgents = 0, kLidarKind = 1, kBoxes = 2, kRamps = 3 };

using Feature = CountHasher::Feature;
constexpr Feature kX{0.0f, 6.0f}, kZ{0.0f, 2.0f}, kUnit{-1.0f, 1.0f}, kVel{-8.0f, 8.0f}, kSpin{-10.0f, 10.0f};
constexpr Feature kFlag{0.0f, 1.0f}, kSize{0.0f, 2.0f}, kRange{0.0f, 6.0f};

}  // namespace

CountState parse_count_state(const std::string& name) {
  if (name == "box_pos") return CountState::kBoxPos;
  if (name == "box_full") return CountState::kBoxFull;
  if (name == "full") return CountState::kFull;
  throw physics::ConfigError("count_state = '" + name +
                             "' is invalid: must be one of box_pos, box_full, full");
}

const std::vector<Feature>& CountHasher::features(CountState state, int kind) {
  static const std::vector<Feature> none;
  // Agents: position, yaw (cos, sin), velocity, angular velocity, hider flag.
  static const std::vector<Feature> agents = {kX, kX, kZ, kUnit, kUnit, kVel, kVel, kVel, kSpin, kFlag};
  static const std::vector<Feature> lidar(size_t(batch::Layout::kLidar), kRange);  // one entity per agent
  static const std::vector<Feature> box_pos = {kX, kX};
  static const std::vector<Feature> box_full = {kX, kX, kZ, kUnit, kUnit, kVel, kVel, kVel};
  // Boxes in full: position, yaw, velocity, angular velocity, size, locked.
  static const std::vector<Feature> box_all = {kX,   kX,    kZ,    kUnit, kUnit, kVel, kVel,
                                               kVel, kSpin, kSize, kSize, kSize, kFlag};
  static const std::vector<Feature> ramps = {kX, kX, kZ, kUnit, kUnit, kVel, kVel, kVel, kSpin, kFlag};
  switch (state) {
    case CountState::kBoxPos:
      return kind == kBoxes ? box_pos : none;
    case CountState::kBoxFull:
      return kind == kBoxes ? box_full : none;
    case CountState::kFull:
    default:
      return kind == kAgents ? agents : kind == kLidarKind ? lidar : kind == kBoxes ? box_all : ramps;
  }
}

CountHasher::CountHasher(CountState state, uint64_t seed) : state_(state) {
  table_.resize(size_t(kKinds) * kMaxFeatures * kCountBins * kCountDigits);
  physics::Rng rng(seed, 0xC0C0C0C0ULL, 0);  // the projection's own stream, shared by every env
  for (uint8_t& d : table_) d = uint8_t(rng.uniform_int(0, 10));
}

int CountHasher::bin(float value, float lo, float hi) {
  const float u = (value - lo) / (hi - lo) * float(kCountBins);
  if (!(u >= 0.0f)) return 0;  // below the range, or NaN
  return std::min(kCountBins - 1, int(u));
}

const uint8_t* CountHasher::embedding(int kind, int feature, int b) const {
  return table_.data() +
         ((size_t(kind) * kMaxFeatures + size_t(feature)) * kCountBins + size_t(b)) * kCountDigits;
}

void CountHasher::digits(const batch::BatchState& s, const batch::Layout& L, int env,
                         std::vector<uint8_t>& out) const {
  out.clear();
  float row[kMaxFeatures];
  for (int kind = 0; kind < kKinds; ++kind) {
    const std::vector<Feature>& fs = features(state_, kind);
    const size_t width = fs.size() * kCountDigits, base = out.size();
    out.resize(base + width, 0);
    if (fs.empty()) continue;
    // Calls pool(row) for every entity of the kind, row holding its features.
    auto pool = [&]() {
      for (size_t f = 0; f < fs.size(); ++f) {
        const uint8_t* e = embedding(kind, int(f), bin(row[f], fs[f].lo, fs[f].hi));
        uint8_t* dst = out.data() + base + f * kCountDigits;
        for (int d = 0; d < kCountDigits; ++d) dst[d] = std::max(dst[d], e[d]);
      }
    };
    // A body's position, yaw (cos, sin), velocity and angular velocity into row[0 .. 8], then `flag` at
    // row[9] (or, for boxes, the size at row[9 .. 11] and the flag at row[12]).
    auto body = [&](const auto& pos, const auto& rot, const auto& vel, const auto& spin, size_t i) {
      std::copy_n(pos.data() + 3 * i, 3, row);
      std::copy_n(rot.data() + 2 * i, 2, row + 3);
      std::copy_n(vel.data() + 3 * i, 3, row + 5);
      row[8] = spin[i];
    };
    const int count = kind == kBoxes ? L.max_boxes : kind == kRamps ? L.max_ramps : L.max_agents;
    for (int k = 0; k < count; ++k) {
      const size_t i = size_t(env) * count + k;
      if (kind == kAgents || kind == kLidarKind) {
        if (s.agent_exists[i] == 0) continue;
        if (kind == kLidarKind) {
          std::copy_n(s.lidar.data() + i * batch::Layout::kLidar, batch::Layout::kLidar, row);
        } else {
          body(s.agent_pos, s.agent_rot, s.agent_vel, s.agent_angvel, i);
          row[9] = float(s.agent_hider[i]);
        }
      } else if (kind == kBoxes) {
        if (s.box_exists[i] == 0) continue;
        body(s.box_pos, s.box_rot, s.box_vel, s.box_angvel, i);  // box_pos, box_full: the first 2, 8
        std::copy_n(s.box_size.data() + 3 * i, 3, row + 9);
        row[12] = float(s.box_locked[i]);
      } else {
        if (s.ramp_exists[i] == 0) continue;
        body(s.ramp_pos, s.ramp_rot, s.ramp_vel, s.ramp_angvel, i);
        row[9] = float(s.ramp_locked[i]);
      }
      pool();
    }
  }
}

uint64_t CountHasher::key(const batch::BatchState& s, const batch::Layout& L, int env) const {
  thread_local std::vector<uint8_t> d;
  digits(s, L, env, d);
  return fnv1a64(d.data(), d.size());
}

float StateCounts::visit(int env, uint64_t key) {
  const uint32_t n = ++counts_[size_t(env)][key];
  return float(scale_ / std::sqrt(double(n)));
}

std::vector<std::vector<std::pair<uint64_t, uint32_t>>> StateCounts::sorted() const {
  std::vector<std::vector<std::pair<uint64_t, uint32_t>>> out(counts_.size());
  for (size_t e = 0; e < counts_.size(); ++e) {
    out[e].assign(counts_[e].begin(), counts_[e].end());
    std::sort(out[e].begin(), out[e].end());
  }
  return out;
}

void StateCounts::restore(const std::vector<std::vector<std::pair<uint64_t, uint32_t>>>& per_env) {
  counts_.assign(per_env.size(), {});
  for (size_t e = 0; e < per_env.size(); ++e) counts_[e].insert(per_env[e].begin(), per_env[e].end());
}

}  // namespace hns::ppo
