// Running observation statistics (docs/game.md §10.2 EMAMeanStd): per-feature debiased EMA of the mean and of
// the mean square, beta 0.99999, one update per batch; std = sqrt(max(E[x^2] - mean^2, 1e-2)). The networks
// normalise with x_hat = clip((x - mean) / std, -5, 5) in a fused SIMD kernel (kernels::normalize_obs),
// reading the float mean and 1/std arrays of ObsNormView.
//
// Features per key: self [self_features], agents [agent_features], boxes [box_features], ramps
// [ramp_features] (shared by every entity of the type), lidar: one channel shared by all rays (the original's
// lidar is [30, 1] and normalises over its last axis); its arrays are expanded to [lidar_rays] for the
// kernel. Before the first update the view is the identity (mean 0, 1/std 1).
#pragma once

#include "nn/tensor.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace hns::nn {

struct ObsShape;

// kObsSites: the fourth entity type (ObsShape::max_sites), only in the scenes that have one; its statistics
// stay empty (no features) elsewhere.
enum ObsKey : int { kObsSelf = 0, kObsLidar, kObsAgents, kObsBoxes, kObsRamps, kObsSites, kNumObsKeys };

// Float arrays the forward pass reads; valid while the normaliser lives and is not updated. The identity
// view (null arrays) says the observations are normalised already: the forward only gathers them.
struct ObsNormView {
  std::array<const float*, kNumObsKeys> mean{};     // [features of the key]
  std::array<const float*, kNumObsKeys> inv_std{};  // [features of the key]
  static ObsNormView identity() { return {}; }
  bool is_identity() const { return mean[kObsSelf] == nullptr; }
};

inline constexpr double kObsNormBeta = 0.99999;
inline constexpr double kObsNormVarFloor = 1e-2;

class ObsNormalizer {
 public:
  explicit ObsNormalizer(const ObsShape& shape, double beta = kObsNormBeta);

  // One EMA update from `rows` agent-steps of raw observations. Every entity slot of a counted row counts,
  // masked entities included, as in the original; rows whose `row_mask` byte is 0 (padding agents of a
  // batch, which the original never has) are skipped, and without any counted row nothing changes. A null
  // row_mask counts every row. Pointers as in NetInputs; a null key is skipped (its statistics and debias
  // term unchanged). Deterministic (sums in index order, in double).
  void update(const float* self, const float* lidar, const float* agents, const float* boxes,
              const float* ramps, const float* sites, int rows, const uint8_t* row_mask = nullptr);
  // The same update from rows that arrive in blocks (a rollout, step by step and env by env, read straight
  // from the simulator): the sums of x and x^2 per feature and the rows counted, per key, filled by
  // add_rows(), merged (summed) with others, and applied as one EMA update. update() is one add_rows() and
  // apply(); sums taken in another grouping differ from it only in rounding.
  struct Sums {
    std::array<std::vector<double>, kNumObsKeys> sum, sq;  // [features of the key]
    std::array<int64_t, kNumObsKeys> rows{};               // rows counted per key (a null key counts none)
    void clear();
    void merge(const Sums& other);
  };
  Sums make_sums() const;
  void add_rows(Sums& sums, const float* self, const float* lidar, const float* agents, const float* boxes,
                const float* ramps, const float* sites, int rows, const uint8_t* row_mask = nullptr) const;
  // The same with the arrays by key (ObsKey order; StepObs::features_from gives them).
  void add_rows(Sums& sums, const std::array<const float*, kNumObsKeys>& by_key, int rows,
                const uint8_t* row_mask = nullptr) const;
  // One EMA update from the sums (keys without counted rows unchanged).
  void apply(const Sums& sums);

  ObsNormView view() const;
  int features(ObsKey key) const { return features_[key]; }
  // Current mean and std of one feature (double precision).
  double mean(ObsKey key, int feature) const;
  double std(ObsKey key, int feature) const;
  double debias(ObsKey key) const { return debias_[key]; }

  // Checkpoint state: biased EMA of the mean and of the square per key, and each key's debias term.
  const std::vector<double>& biased_mean(ObsKey key) const { return biased_mean_[key]; }
  const std::vector<double>& biased_sq(ObsKey key) const { return biased_sq_[key]; }
  void set_state(const std::array<std::vector<double>, kNumObsKeys>& biased_mean,
                 const std::array<std::vector<double>, kNumObsKeys>& biased_sq,
                 const std::array<double, kNumObsKeys>& debias);

 private:
  void refresh();

  double beta_;
  std::array<double, kNumObsKeys> debias_{};       // per key, sum of (1 - beta) beta^k: the debiasing divisor
  std::array<int, kNumObsKeys> features_{};        // features per key (lidar: 1 channel)
  std::array<int, kNumObsKeys> expanded_{};        // length of the float arrays (lidar: rays)
  std::array<int, kNumObsKeys> values_per_row_{};  // floats per agent-step (entities x features)
  std::array<std::vector<double>, kNumObsKeys> biased_mean_;
  std::array<std::vector<double>, kNumObsKeys> biased_sq_;
  std::array<std::vector<float>, kNumObsKeys> mean_f_;
  std::array<std::vector<float>, kNumObsKeys> inv_std_f_;
};

}  // namespace hns::nn
