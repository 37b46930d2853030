// Random network distillation (intrinsic = rnd): the reward is the mean squared difference of the predictor's
// and the target's 64 outputs (checked against hand values by giving the predictor the target's weights and
// known output offsets); the networks have no LSTM and the predictor's gradient matches finite differences;
// training shrinks the error on the rows it learns from; bits do not depend on the thread count; a training
// run logs the intrinsic return apart and resumes bit for bit with its predictor.
#include "ppo/rnd.hpp"

#include <gtest/gtest.h>
#include <oneapi/tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "../nn/test_util.hpp"
#include "nn/obs_store.hpp"
#include "ppo/trainer.hpp"
#include "ppo_test_util.hpp"

namespace hns::ppo {
namespace {

using nn::testing::random_mask;
using nn::testing::random_vector;

// Random observations of the tiny network's shape (every entity type present, some masked): the features and
// the value net's masks, which the RND networks read (the policy's masks and the resets stay 0).
nn::ObsStore random_rows(const nn::ObsShape& s, int n, uint64_t seed) {
  nn::ObsStore rows(s, size_t(n));
  auto put = [](nn::FloatBuffer& dst, const std::vector<float>& v) {
    ASSERT_EQ(v.size(), dst.size());
    std::copy(v.begin(), v.end(), dst.data());
  };
  put(rows.self, random_vector(size_t(n) * s.self_features, seed + 1, -2, 2));
  put(rows.lidar, random_vector(size_t(n) * s.lidar_rays, seed + 2, 0, 6));
  put(rows.agents, random_vector(size_t(n) * s.num_other_agents() * s.agent_features, seed + 3, -2, 2));
  put(rows.boxes, random_vector(size_t(n) * s.max_boxes * s.box_features, seed + 4, -2, 2));
  put(rows.ramps, random_vector(size_t(n) * s.max_ramps * s.ramp_features, seed + 5, -2, 2));
  put(rows.sites, random_vector(size_t(n) * s.max_sites * s.site_features, seed + 6, -2, 2));
  put(rows.agents_present, random_mask(size_t(n) * s.num_other_agents(), seed + 7, 0.8));
  put(rows.boxes_present, random_mask(size_t(n) * s.max_boxes, seed + 8, 0.8));
  put(rows.ramps_present, random_mask(size_t(n) * s.max_ramps, seed + 9, 0.8));
  put(rows.sites_present, random_mask(size_t(n) * s.max_sites, seed + 10, 0.8));
  return rows;
}

// With the target's weights the predictor's error is exactly 0; with its output biases moved by d_k = k / 64
// every row's error is mean_k d_k^2 = (sum of k^2 for k < 64) / 64^3 = 85344 / 262144.
TEST(Rnd, ErrorIsTheMeanSquaredDifferenceOfTheTwoNetworks) {
  const nn::NetConfig cfg = nn::testing::tiny_net_config();
  Rnd rnd(cfg, 5, 1e-3f);
  EXPECT_EQ(rnd.config().lstm, 0);
  ASSERT_EQ(rnd.predictor().buffer_floats(), rnd.target().buffer_floats());
  const int n = 150;  // three chunks, the last one partial
  const nn::ObsStore rows = random_rows(cfg.obs, n, 40);
  std::vector<float> err(n);
  rnd.errors(nn::ObsNormView::identity(), rows.batch(), n, err.data());
  for (float e : err) EXPECT_GT(e, 0.01f) << "two random networks disagree";

  std::memcpy(rnd.predictor().values(), rnd.target().values(), rnd.target().buffer_floats() * sizeof(float));
  rnd.errors(nn::ObsNormView::identity(), rows.batch(), n, err.data());
  for (float e : err) EXPECT_EQ(e, 0.0f);

  std::span<float> bias = rnd.predictor().slice("rnd_predictor/projection/b");
  ASSERT_EQ(bias.size(), 64u);
  for (size_t k = 0; k < 64; ++k) bias[k] += float(k) / 64.0f;
  rnd.errors(nn::ObsNormView::identity(), rows.batch(), n, err.data());
  for (float e : err) EXPECT_NEAR(e, 85344.0 / 262144.0, 2e-5);
}

// The networks drop the LSTM: the predictor's gradient (of the summed error over a chunk) matches finite
// differences, slice by slice, through the whole network.
TEST(Rnd, PredictorGradientMatchesFiniteDifferences) {
  const nn::NetConfig cfg = nn::testing::tiny_net_config();
  Rnd rnd(cfg, 6, 0.0f);  // lr 0: the step leaves the weights, the gradient stays in grads()
  const int n = 150;      // more than two 64-row chunks: the chunks' and groups' sums are checked too
  const nn::ObsStore rows = random_rows(cfg.obs, n, 41);
  std::vector<int32_t> all(n);
  for (int i = 0; i < n; ++i) all[size_t(i)] = i;
  auto loss = [&]() {
    std::vector<float> err(n);
    rnd.errors(nn::ObsNormView::identity(), rows.batch(), n, err.data());
    double sum = 0;
    for (float e : err) sum += e;
    return sum / n;
  };
  const double before = rnd.train(nn::ObsNormView::identity(), rows.batch(), all);
  EXPECT_NEAR(before, loss(), 1e-5);
  const std::vector<float> analytic(rnd.predictor().grads(),
                                    rnd.predictor().grads() + rnd.predictor().buffer_floats());
  int checked = 0;
  for (const nn::testing::SliceCheck& c : nn::testing::check_param_gradient(
           rnd.predictor().values(), rnd.predictor().layout(), analytic, 6, loss)) {
    if (c.ref2 < 1e-8) continue;
    ++checked;
    EXPECT_LT(std::sqrt(c.err2), 0.03 * std::sqrt(c.ref2) + 2e-3) << c.name;
  }
  EXPECT_GT(checked, 20);
  EXPECT_EQ(rnd.predictor().layout().find("rnd_predictor/lstm/w_x"), nullptr);
}

// Training on rows A shrinks their error far more than that of rows B from elsewhere, which it never sees;
// and the steps are the same bits on one thread and on two.
TEST(Rnd, TrainingShrinksTheErrorOfVisitedRowsAndIsBitIdenticalAcrossThreads) {
  const nn::NetConfig cfg = nn::testing::tiny_net_config();
  const int n = 200;
  const nn::ObsStore seen = random_rows(cfg.obs, n, 50);
  nn::ObsStore unseen =
      random_rows(cfg.obs, n, 60);  // another part of the observation space: what the agents never visited
  for (float& v : unseen.self.span()) v += 4.0f;
  for (float& v : unseen.boxes.span()) v -= 4.0f;
  std::vector<int32_t> all(n);
  for (int i = 0; i < n; ++i) all[size_t(i)] = i;
  auto mean_error = [&](const Rnd& r, const nn::ObsStore& rows) {
    std::vector<float> err(n);
    r.errors(nn::ObsNormView::identity(), rows.batch(), n, err.data());
    double s = 0;
    for (float e : err) s += e;
    return s / n;
  };
  auto run = [&](int threads) {
    auto rnd = std::make_unique<Rnd>(cfg, 7, 3e-3f);
    tbb::task_arena arena(threads);
    arena.execute([&] {
      for (int k = 0; k < 150; ++k) rnd->train(nn::ObsNormView::identity(), seen.batch(), all);
    });
    return rnd;
  };
  const Rnd fresh(cfg, 7, 3e-3f);
  const auto one = run(1), two = run(2);
  const double seen_before = mean_error(fresh, seen), unseen_before = mean_error(fresh, unseen);
  const double seen_after = mean_error(*one, seen), unseen_after = mean_error(*one, unseen);
  EXPECT_LT(seen_after, 0.2 * seen_before);
  EXPECT_LT(seen_after / seen_before, 0.7 * (unseen_after / unseen_before));
  EXPECT_EQ(0, std::memcmp(one->predictor().values(), two->predictor().values(),
                           one->predictor().buffer_floats() * sizeof(float)));
}

using testing::metrics_but_timings;

TrainConfig rnd_config() {
  return testing::tiny_intrinsic_config("rnd");
}

TEST(Rnd, TrainingLogsTheIntrinsicReturnApartAndResumesWithItsPredictor) {
  TrainConfig plain = rnd_config();
  plain.intrinsic = "none";
  Trainer without(plain);
  const IterationMetrics m0 = without.iterate();
  Trainer with(rnd_config());
  const IterationMetrics m1 = with.iterate();
  EXPECT_EQ(m1.hider_reward, m0.hider_reward) << "the same seeded policy acts first";
  EXPECT_EQ(m0.intrinsic_reward, 0.0);
  EXPECT_GT(m1.intrinsic_reward, 0.0);
  EXPECT_GT(m1.t_intrinsic, 0.0);
  EXPECT_NE(rnd_config().to_json().find("\"intrinsic\": \"rnd\""), std::string::npos);

  const std::string path = ::testing::TempDir() + "rnd_resume_" + std::to_string(::getpid()) + ".bin";
  with.save(path);
  const std::string second = metrics_but_timings(with.iterate());
  const std::string third = metrics_but_timings(with.iterate());
  Trainer resumed(rnd_config());
  resumed.load(path);
  // (With the seed's predictor instead of the trained one, the second iteration's intrinsic rewards would
  // differ; without the predictor's Adam moments and step count, the third's.)
  EXPECT_EQ(metrics_but_timings(resumed.iterate()), second);
  EXPECT_EQ(metrics_but_timings(resumed.iterate()), third);
  std::remove(path.c_str());

  TrainConfig bad = rnd_config();
  bad.rnd_scale = -1;
  EXPECT_THROW(bad.validate(), physics::ConfigError);
}

// The learning smoke test of RND: as the predictor learns the states the agents visit, their intrinsic
// return falls (six iterations of 4 quadrant envs, a second or two).
TEST(Rnd, TheIntrinsicReturnFallsAsThePredictorLearns) {
  TrainConfig c = rnd_config();
  c.envs = 4;
  c.horizon = 40;
  Trainer t(c);
  const double first = t.iterate().intrinsic_reward;
  double last = first;
  for (int i = 0; i < 5; ++i) last = t.iterate().intrinsic_reward;
  EXPECT_GT(first, 0.0);
  EXPECT_LT(last, 0.8 * first);
}

}  // namespace
}  // namespace hns::ppo
