// Helpers shared by the nn tests: deterministic random data and central-difference gradient checks.
#pragma once

#include "nn/entity_net.hpp"
#include "nn/params.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

namespace hns::nn::testing {

// A network with the paper's structure and tiny widths (fast to check exhaustively).
inline NetConfig tiny_net_config() {
  NetConfig c;
  c.obs.self_features = 4;
  c.obs.max_agents = 3;
  c.obs.agent_features = 3;
  c.obs.max_boxes = 2;
  c.obs.box_features = 5;
  c.obs.max_ramps = 1;
  c.obs.ramp_features = 4;
  c.obs.max_sites = 2;
  c.obs.site_features = 3;
  c.obs.lidar_rays = 8;
  c.lidar_filters = 3;
  c.embed = 8;
  c.heads = 2;
  c.dense = 10;
  c.lstm = 6;
  c.action_heads = {3, 2};
  return c;
}

// Central differences of loss() w.r.t. the flat parameters p, compared with the analytic gradient, at about
// `per_slice` evenly spread coordinates of every slice of `layout`. Two step sizes: ReLU and clipping kinks
// crossed by the perturbation bias larger steps (the error shrinks linearly with the step), float rounding
// limits smaller ones to a few 1e-3; a coordinate where the two disagree sits on a kink and is skipped.
struct SliceCheck {
  std::string name;
  double err2 = 0.0;  // sum of (fd - analytic)^2
  double ref2 = 0.0;  // sum of fd^2
  int coords = 0, skipped = 0;
};
inline std::vector<SliceCheck> check_param_gradient(float* p, const ParamLayout& layout,
                                                    const std::vector<float>& analytic, size_t per_slice,
                                                    const std::function<double()>& loss) {
  auto central = [&](size_t k, float h) {
    const float v = p[k];
    p[k] = v + h;
    const double lp = loss();
    p[k] = v - h;
    const double lm = loss();
    p[k] = v;
    return (lp - lm) / (static_cast<double>(v + h) - static_cast<double>(v - h));
  };
  std::vector<SliceCheck> out;
  for (const ParamSlice& s : layout.slices()) {
    SliceCheck c{s.name};
    const size_t step = std::max<size_t>(1, s.size() / per_slice);
    for (size_t i = 0; i < s.size(); i += step) {
      const size_t k = s.offset + i;
      const double fd1 = central(k, 5e-4f);
      const double fd2 = central(k, 2.5e-4f);
      ++c.coords;
      if (std::fabs(fd1 - fd2) > 4e-3 + 2e-2 * std::fabs(fd2)) {
        ++c.skipped;
        continue;
      }
      c.err2 += (fd2 - analytic[k]) * (fd2 - analytic[k]);
      c.ref2 += fd2 * fd2;
    }
    out.push_back(c);
  }
  return out;
}

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
