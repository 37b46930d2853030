// Helpers shared by the nn tests: deterministic random data and central-difference gradient checks.
#pragma once

#include "nn/params.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

namespace hns::nn::testing {

// Uniform floats in [lo, hi) from a fixed stream.
inline std::vector<float> random_vector(size_t n, uint64_t seed, float lo = -1.0f, float hi = 1.0f) {
  InitRng rng(seed, 7);
  std::vector<float> v(n);
  for (auto& x : v) x = static_cast<float>(lo + (hi - lo) * rng.uniform());
  return v;
}

// 0/1 mask with about `p_one` ones.
inline std::vector<float> random_mask(size_t n, uint64_t seed, double p_one = 0.6) {
  InitRng rng(seed, 11);
  std::vector<float> v(n);
  for (auto& x : v) x = rng.uniform() < p_one ? 1.0f : 0.0f;
  return v;
}

inline std::vector<double> to_double(const std::vector<float>& v) {
  return {v.begin(), v.end()};
}

// Compares an analytic gradient with central differences of a double-precision loss at `point`:
// max_i |analytic_i - fd_i| <= tol * max(max_i |fd_i|, floor). Checks every coordinate, or an evenly spread
// subset of `max_coords` of them.
inline void expect_gradient_matches(const std::function<double(const std::vector<double>&)>& loss,
                                    std::vector<double> point, const std::vector<float>& analytic, double tol,
                                    const std::string& what, size_t max_coords = 600, double h = 1e-6,
                                    double floor = 1e-3) {
  ASSERT_EQ(point.size(), analytic.size()) << what;
  const size_t n = point.size();
  const size_t step = std::max<size_t>(1, (n + max_coords - 1) / max_coords);
  std::vector<double> fd;
  std::vector<size_t> idx;
  for (size_t i = 0; i < n; i += step) {
    const double v = point[i];
    point[i] = v + h;
    const double lp = loss(point);
    point[i] = v - h;
    const double lm = loss(point);
    point[i] = v;
    fd.push_back((lp - lm) / (2.0 * h));
    idx.push_back(i);
  }
  double scale = floor;
  for (double g : fd) scale = std::max(scale, std::fabs(g));
  double worst = 0.0;
  size_t worst_i = 0;
  for (size_t k = 0; k < idx.size(); ++k) {
    const double err = std::fabs(analytic[idx[k]] - fd[k]);
    if (err > worst) {
      worst = err;
      worst_i = k;
    }
  }
  EXPECT_LE(worst / scale, tol) << what << ": coordinate " << idx[worst_i] << " analytic "
                                << analytic[idx[worst_i]] << " vs finite difference " << fd[worst_i]
                                << " (gradient scale " << scale << ")";
  // The check must not pass vacuously.
  EXPECT_GT(scale, floor) << what << ": gradient is zero everywhere";
}

}  // namespace hns::nn::testing
