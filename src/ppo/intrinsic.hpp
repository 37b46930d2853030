// Count-based exploration (the paper's appendix "Intrinsic motivation"): an intrinsic reward 0.1 / √N(S) for
// the N-th visit of a hashed, object-invariant state S, counted per env (a "rollout worker" of the paper,
// which keeps its own counts while every worker shares the random projection).
//
// The state S of an env, from the batch state after a step:
//   1. each entity of a kind (agent, lidar, box, ramp) is a row of real features (CountState below says
//      which, per representation);
//   2. every feature is discretised into 30 bins over its fixed range (positions 0..6 m, velocities ±8 m/s,
//      ...; values outside land in the first or last bin);
//   3. each (kind, feature, bin) has a fixed random embedding of 16 digits 0..9 (drawn once from the run's
//      seed), and an entity's embedding is the concatenation of its features' embeddings;
//   4. the entities of a kind are max-pooled digit by digit (no entity: all digits 0), the kinds
//   concatenated;
//   5. S is the FNV-1a 64 hash of those digits.
#pragma once

#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "batch/batch_sim.hpp"

namespace hns::ppo {

// The paper's three state representations: boxes' 2-D positions (single agent); boxes' position, rotation
// and velocity (single agent); everything a hide-and-seek policy observes (agents, lidar, boxes, ramps).
enum class CountState : uint8_t { kBoxPos, kBoxFull, kFull };
// "box_pos", "box_full", "full"; throws physics::ConfigError naming the allowed values.
CountState parse_count_state(const std::string& name);

inline constexpr int kCountBins = 30;
inline constexpr int kCountDigits = 16;

class CountHasher {
 public:
  CountHasher(CountState state, uint64_t seed);
  // The pooled digits of env e (kinds in the order agents, lidar, boxes, ramps; each kind's features x 16).
  void digits(const batch::BatchState& s, const batch::Layout& L, int env, std::vector<uint8_t>& out) const;
  // The state key of env e: FNV-1a 64 of digits().
  uint64_t key(const batch::BatchState& s, const batch::Layout& L, int env) const;
  // The bin of a value within [lo, hi] (clamped into 0 .. 29).
  static int bin(float value, float lo, float hi);
  // The embedding of (kind, feature, bin): 16 digits.
  const uint8_t* embedding(int kind, int feature, int bin) const;

  // A feature of an entity kind: its range for the bins.
  struct Feature {
    float lo, hi;
  };
  static const std::vector<Feature>& features(CountState state, int kind);
  static constexpr int kKinds = 4;  // agents, lidar, boxes, ramps

 private:
  CountState state_;
  std::vector<uint8_t> table_;  // [kind][feature][bin][digit], features padded to kMaxFeatures
  static constexpr int kMaxFeatures = 30;
};

// Counts of one run, per env, and the intrinsic reward.
class StateCounts {
 public:
  StateCounts(int envs, double scale) : counts_(size_t(envs)), scale_(scale) {}
  // Counts a visit of `key` in env e; returns scale / √N after the visit.
  float visit(int env, uint64_t key);
  int64_t distinct(int env) const { return int64_t(counts_[size_t(env)].size()); }
  // Every env's (key, count) pairs sorted by key: the checkpoint's form.
  std::vector<std::vector<std::pair<uint64_t, uint32_t>>> sorted() const;
  void restore(const std::vector<std::vector<std::pair<uint64_t, uint32_t>>>& per_env);

 private:
  std::vector<std::unordered_map<uint64_t, uint32_t>> counts_;
  double scale_;
};

}  // namespace hns::ppo
