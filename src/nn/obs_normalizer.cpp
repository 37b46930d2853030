#include "nn/obs_normalizer.hpp"

#include "nn/entity_net.hpp"

#include <algorithm>
#include <cmath>

namespace hns::nn {

ObsNormalizer::ObsNormalizer(const ObsShape& shape, double beta) : beta_(beta) {
  const int site_features = shape.max_sites > 0 ? shape.site_features : 0;
  features_ = {shape.self_features, 1, shape.agent_features, shape.box_features, shape.ramp_features,
               site_features};
  expanded_ = {shape.self_features, shape.lidar_rays,    shape.agent_features,
               shape.box_features,  shape.ramp_features, site_features};
  values_per_row_ = {shape.self_features,
                     shape.lidar_rays,
                     shape.num_other_agents() * shape.agent_features,
                     shape.max_boxes * shape.box_features,
                     shape.max_ramps * shape.ramp_features,
                     shape.max_sites * site_features};
  for (int k = 0; k < kNumObsKeys; ++k) {
    biased_mean_[k].assign(features_[k], 0.0);
    biased_sq_[k].assign(features_[k], 0.0);
    mean_f_[k].assign(std::max(expanded_[k], 1), 0.0f);
    inv_std_f_[k].assign(std::max(expanded_[k], 1), 1.0f);
  }
}

void ObsNormalizer::update(const float* self, const float* lidar, const float* agents, const float* boxes,
                           const float* ramps, const float* sites, int rows, const uint8_t* row_mask) {
  Sums sums = make_sums();
  add_rows(sums, self, lidar, agents, boxes, ramps, sites, rows, row_mask);
  apply(sums);
}

void ObsNormalizer::Sums::clear() {
  for (int k = 0; k < kNumObsKeys; ++k) {
    std::fill(sum[k].begin(), sum[k].end(), 0.0);
    std::fill(sq[k].begin(), sq[k].end(), 0.0);
    rows[k] = 0;
  }
}

void ObsNormalizer::Sums::merge(const Sums& other) {
  for (int k = 0; k < kNumObsKeys; ++k) {
    HNS_NN_CHECK(sum[k].size() == other.sum[k].size(), "observation sums of another shape");
    for (size_t j = 0; j < sum[k].size(); ++j) {
      sum[k][j] += other.sum[k][j];
      sq[k][j] += other.sq[k][j];
    }
    rows[k] += other.rows[k];
  }
}

ObsNormalizer::Sums ObsNormalizer::make_sums() const {
  Sums s;
  for (int k = 0; k < kNumObsKeys; ++k) {
    s.sum[k].assign(features_[k], 0.0);
    s.sq[k].assign(features_[k], 0.0);
  }
  return s;
}

void ObsNormalizer::add_rows(Sums& sums, const float* self, const float* lidar, const float* agents,
                             const float* boxes, const float* ramps, const float* sites, int rows,
                             const uint8_t* row_mask) const {
  add_rows(sums, {self, lidar, agents, boxes, ramps, sites}, rows, row_mask);
}

void ObsNormalizer::add_rows(Sums& sums, const std::array<const float*, kNumObsKeys>& data, int rows,
                             const uint8_t* row_mask) const {
  for (int k = 0; k < kNumObsKeys; ++k) {
    if (data[k] == nullptr || values_per_row_[k] == 0) continue;
    const int f = features_[k];
    HNS_NN_CHECK(sums.sum[k].size() == static_cast<size_t>(f), "observation sums of another shape");
    const size_t per_row = static_cast<size_t>(values_per_row_[k]);
    double* sum = sums.sum[k].data();
    double* sq = sums.sq[k].data();
    for (int r = 0; r < rows; ++r) {
      if (row_mask != nullptr && row_mask[r] == 0) continue;
      ++sums.rows[k];
      const float* row = data[k] + static_cast<size_t>(r) * per_row;
      for (size_t i = 0; i < per_row; i += static_cast<size_t>(f)) {
        for (int j = 0; j < f; ++j) {
          const double v = row[i + j];
          sum[j] += v;
          sq[j] += v * v;
        }
      }
    }
  }
}

void ObsNormalizer::apply(const Sums& sums) {
  for (int k = 0; k < kNumObsKeys; ++k) {
    if (sums.rows[k] == 0) continue;
    const int f = features_[k];
    HNS_NN_CHECK(sums.sum[k].size() == static_cast<size_t>(f), "observation sums of another shape");
    const double count =
        static_cast<double>(static_cast<size_t>(sums.rows[k]) * static_cast<size_t>(values_per_row_[k]) / f);
    for (int j = 0; j < f; ++j) {
      biased_mean_[k][j] = beta_ * biased_mean_[k][j] + (1.0 - beta_) * sums.sum[k][j] / count;
      biased_sq_[k][j] = beta_ * biased_sq_[k][j] + (1.0 - beta_) * sums.sq[k][j] / count;
    }
    debias_[k] = beta_ * debias_[k] + (1.0 - beta_);
  }
  refresh();
}

double ObsNormalizer::mean(ObsKey key, int feature) const {
  return debias_[key] > 0.0 ? biased_mean_[key][feature] / debias_[key] : 0.0;
}

double ObsNormalizer::std(ObsKey key, int feature) const {
  if (debias_[key] <= 0.0) return 1.0;
  const double m = mean(key, feature);
  const double sq = biased_sq_[key][feature] / debias_[key];
  return std::sqrt(std::max(sq - m * m, kObsNormVarFloor));
}

void ObsNormalizer::refresh() {
  for (int k = 0; k < kNumObsKeys; ++k) {
    for (int i = 0; i < expanded_[k]; ++i) {
      const int j = k == kObsLidar ? 0 : i;
      mean_f_[k][i] = static_cast<float>(mean(static_cast<ObsKey>(k), j));
      inv_std_f_[k][i] = static_cast<float>(1.0 / std(static_cast<ObsKey>(k), j));
    }
  }
}

void ObsNormalizer::set_state(const std::array<std::vector<double>, kNumObsKeys>& biased_mean,
                              const std::array<std::vector<double>, kNumObsKeys>& biased_sq,
                              const std::array<double, kNumObsKeys>& debias) {
  for (int k = 0; k < kNumObsKeys; ++k) {
    HNS_NN_CHECK(
        biased_mean[k].size() == biased_mean_[k].size() && biased_sq[k].size() == biased_sq_[k].size(),
        "observation normaliser state has the wrong feature count");
  }
  biased_mean_ = biased_mean;
  biased_sq_ = biased_sq;
  debias_ = debias;
  refresh();
}

ObsNormView ObsNormalizer::view() const {
  ObsNormView v;
  for (int k = 0; k < kNumObsKeys; ++k) {
    v.mean[k] = mean_f_[k].data();
    v.inv_std[k] = inv_std_f_[k].data();
  }
  return v;
}

}  // namespace hns::nn
