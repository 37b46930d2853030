// Stage detection over metrics rows (docs/training.md "Stages"): windows of whole iterations holding
// kStageWindowEpisodes episodes, episode-weighted means and ratios, the first row that meets a criterion,
// rows without a statistic left out of its windows.
#include "replay/stages.hpp"

#include "batch/batch_sim.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace hns::replay {
namespace {

// metrics.jsonl text: `n` iterations of `episodes` episodes each; from iteration `sealed_from` on, every
// episode seals both of its two doors, before it none does. Rows before `stats_from`, and every
// `gap_every`-th row, lack the detectors.
std::string quadrant_rows(int n, int episodes, int sealed_from, int stats_from = 1, int gap_every = 0) {
  std::string text;
  for (int i = 1; i <= n; ++i) {
    text += "{\"iteration\": " + std::to_string(i) + ", \"agent_steps\": " + std::to_string(i * 1000) +
            ", \"episodes\": " + std::to_string(episodes);
    if (i >= stats_from && !(gap_every > 0 && i % gap_every == 0)) {
      text += ", \"num_doors\": 2, \"num_door_sealed_prep\": " + std::string(i >= sealed_from ? "2" : "0") +
              ", \"seeker_approach\": 0.1, \"seeker_high_seen\": 0, \"ramp_in_room_prep\": 0.1";
    }
    text += "}\n";
  }
  return text;
}

const StageTrack& stage(const StageReport& r, const std::string& name) {
  for (const StageTrack& t : r.stages) {
    if (t.name == name) return t;
  }
  throw std::runtime_error("no stage " + name);
}

TEST(Stages, FortBuildingAppearsWhenHalfTheWindowSealsItsDoors) {
  // 100 episodes per iteration: a window is 10 iterations. Sealing starts at iteration 31; the window ending
  // at iteration 35 holds 5 sealing iterations of 10: half the doors.
  const StageReport r = detect_stages(read_metrics_jsonl(quadrant_rows(60, 100, 31)), "quadrant");
  ASSERT_EQ(r.stages.size(), 5u);
  const StageTrack& fort = stage(r, "fort building");
  EXPECT_EQ(fort.first_iteration, 35);
  EXPECT_EQ(fort.first_agent_steps, 35000);
  EXPECT_EQ(fort.first_episodes, 3500);
  EXPECT_TRUE(std::isnan(fort.value[8])) << "iteration 9: fewer than 1000 episodes so far";
  EXPECT_DOUBLE_EQ(fort.value[9], 0.0);
  EXPECT_DOUBLE_EQ(fort.value[33], 0.4);
  EXPECT_DOUBLE_EQ(fort.value[59], 1.0);
  EXPECT_EQ(fort.on[33], 0);
  EXPECT_EQ(fort.on[34], 1);
  EXPECT_EQ(stage(r, "running and chasing").first_row, -1) << "0.1 m/s is not chasing";
  EXPECT_EQ(stage(r, "ramp defence").first_row, -1);
  const auto lines = r.summary();
  ASSERT_EQ(lines.size(), 5u);
  EXPECT_EQ(lines[1], "fort building: from iteration 35 (35k agent-steps, 3500 episodes)");
  EXPECT_EQ(lines[0], "running and chasing: not reached (last window 0.1, needs >= 0.25)");
}

TEST(Stages, RowsWithoutTheStatisticsAreLeftOut) {
  // A run resumed by a newer hns: the first 40 rows have no detectors. Sealing from iteration 41 on is then
  // the whole window as soon as the window is full, at iteration 50.
  const StageReport r = detect_stages(read_metrics_jsonl(quadrant_rows(60, 100, 41, 41)), "quadrant");
  const StageTrack& fort = stage(r, "fort building");
  EXPECT_TRUE(std::isnan(fort.value[48]));
  EXPECT_EQ(fort.first_iteration, 50);
  EXPECT_EQ(fort.first_episodes, 5000) << "episodes count from the run's start";
}

TEST(Stages, SmallIterationsMakeLongWindowsAndOtherScenesHaveNone) {
  const StageReport r = detect_stages(read_metrics_jsonl(quadrant_rows(400, 4, 201)), "quadrant");
  EXPECT_EQ(stage(r, "fort building").first_iteration, 325) << "windows of 250 iterations of 4 episodes";
  EXPECT_TRUE(detect_stages(read_metrics_jsonl(quadrant_rows(10, 100, 1)), "lockbox").stages.empty());
  EXPECT_EQ(detect_stages(read_metrics_jsonl(quadrant_rows(10, 100, 1)), "full").stages.size(), 5u);
}

// The tracker `hns train` announces stages with sees the rows one at a time and reaches each stage at the
// same row as the whole-file detection, once.
TEST(Stages, TrackerMatchesTheWholeFileDetection) {
  const std::string text = quadrant_rows(60, 100, 31, 5);
  const StageReport whole = detect_stages(read_metrics_jsonl(text), "quadrant");
  StageTracker tracker("quadrant");
  std::vector<int> reached_at(whole.stages.size(), -1);
  size_t start = 0;
  for (int row = 0; start < text.size(); ++row) {
    const size_t end = text.find('\n', start);
    for (int k : tracker.add(std::string_view(text).substr(start, end - start))) {
      EXPECT_EQ(reached_at[size_t(k)], -1) << "stage " << k << " announced twice";
      reached_at[size_t(k)] = row;
    }
    start = end + 1;
  }
  for (size_t k = 0; k < whole.stages.size(); ++k) {
    EXPECT_EQ(reached_at[k], whole.stages[k].first_row) << whole.stages[k].name;
    EXPECT_EQ(tracker.stages()[k].first_episodes, whole.stages[k].first_episodes);
    EXPECT_EQ(std::isnan(tracker.value(int(k))), std::isnan(whole.stages[k].value.back()));
  }
  EXPECT_EQ(reached_at[1], 34) << "fort building";
  EXPECT_DOUBLE_EQ(tracker.value(1), 1.0);
  EXPECT_TRUE(tracker.add("not json").empty()) << "a line that is not a row adds nothing";
  EXPECT_DOUBLE_EQ(tracker.value(1), 1.0) << "nor changes a window";
}

TEST(Stages, RowsWithoutStatisticsInsideTheWindowAndOneHugeRow) {
  // Every even row lacks the detectors: a window spans 20 rows (10 that count), and sealing from iteration
  // 51 on fills half of one (51, 53, ..., 59 of 41 ... 59) at iteration 59.
  const StageReport gaps = detect_stages(read_metrics_jsonl(quadrant_rows(100, 100, 51, 1, 2)), "quadrant");
  EXPECT_EQ(stage(gaps, "fort building").first_iteration, 59);
  EXPECT_EQ(stage(gaps, "fort building").first_episodes, 5900) << "every row's episodes count for the run";
  // One iteration of 5000 episodes is a window on its own.
  const StageReport huge = detect_stages(read_metrics_jsonl(quadrant_rows(3, 5000, 2)), "quadrant");
  EXPECT_EQ(stage(huge, "fort building").first_iteration, 2);
  EXPECT_DOUBLE_EQ(stage(huge, "fort building").value[0], 0.0);
  EXPECT_DOUBLE_EQ(stage(huge, "fort building").value[1], 1.0);
}

TEST(Stages, QuadrantBoxSurfingFromItsShareOfEpisodes) {
  std::string text;
  for (int i = 1; i <= 30; ++i) {
    text += "{\"iteration\": " + std::to_string(i) + ", \"agent_steps\": " + std::to_string(i * 100) +
            ", \"episodes\": 100, \"box_surf\": " + (i > 20 ? "0.15" : "0.05") + "}\n";
  }
  const StageReport r = detect_stages(read_metrics_jsonl(text), "quadrant");
  // Windows of 10 iterations: 0.05 x (10 - k) + 0.15 x k >= 0.1 from k = 5, iteration 25.
  EXPECT_EQ(stage(r, "box surfing").first_iteration, 25);
  EXPECT_EQ(stage(r, "fort building").first_row, -1) << "no door statistics in these rows";
}

// hns report --windows: rows go to the window of their last agent-step, each detector is the
// episode-weighted mean over the rows that have it, the door detectors per door (a ratio of sums).
TEST(Stages, DetectorWindowsAreEpisodeWeightedMeansPerWindowOfAgentSteps) {
  const std::string text =
      // window [0, 2500): rows ending at 1000 and 2000
      "{\"iteration\": 1, \"agent_steps\": 1000, \"episodes\": 10, \"hider_reward\": 4, "
      "\"num_doors\": 1, \"num_door_sealed_prep\": 1, \"entropy\": 8}\n"
      "{\"iteration\": 2, \"agent_steps\": 2000, \"episodes\": 30, \"hider_reward\": -4, "
      "\"num_doors\": 2, \"num_door_sealed_prep\": 1, \"entropy\": 6}\n"
      // window [2500, 5000): the row ending at exactly 5000 is in it; the row at 4000 has no detectors
      "{\"iteration\": 3, \"agent_steps\": 3000, \"episodes\": 5, \"hider_reward\": 1}\n"
      "{\"iteration\": 4, \"agent_steps\": 4000, \"episodes\": 7}\n"
      "{\"iteration\": 5, \"agent_steps\": 5000, \"episodes\": 15, \"hider_reward\": 5}\n"
      // window [5000, 7500) is empty and left out; [7500, 10000) holds the last row
      "{\"iteration\": 6, \"agent_steps\": 8000, \"episodes\": 2, \"hider_reward\": 0, "
      "\"seeker_approach\": 0.5}\n";
  const DetectorTable t = detector_windows(read_metrics_jsonl(text), 2500);
  const auto& cols = DetectorTable::columns();
  auto col = [&](const char* key) {
    for (size_t c = 0; c < cols.size(); ++c)
      if (std::string_view(cols[c].key) == key) return c;
    throw std::runtime_error(std::string("no column ") + key);
  };
  ASSERT_EQ(t.windows.size(), 3u);
  const DetectorWindow& w0 = t.windows[0];
  EXPECT_EQ(w0.begin, 0);
  EXPECT_EQ(w0.end, 2500);
  EXPECT_EQ(w0.last_agent_steps, 2000);
  EXPECT_EQ(w0.iterations, 2);
  EXPECT_EQ(w0.episodes, 40);
  EXPECT_DOUBLE_EQ(w0.mean[col("hider_reward")], (4.0 * 10 - 4.0 * 30) / 40);
  EXPECT_DOUBLE_EQ(w0.mean[col("entropy")], (8.0 * 10 + 6.0 * 30) / 40);
  // Per door: (1 x 10 + 1 x 30) / (1 x 10 + 2 x 30), not the mean of the rows' ratios.
  EXPECT_DOUBLE_EQ(w0.mean[col("num_door_sealed_prep")], 40.0 / 70.0);
  EXPECT_TRUE(std::isnan(w0.mean[col("seeker_approach")]));
  const DetectorWindow& w1 = t.windows[1];
  EXPECT_EQ(w1.begin, 2500);
  EXPECT_EQ(w1.last_agent_steps, 5000);
  EXPECT_EQ(w1.iterations, 3);
  EXPECT_EQ(w1.episodes, 27);
  EXPECT_DOUBLE_EQ(w1.mean[col("hider_reward")], (1.0 * 5 + 5.0 * 15) / 20) << "the row without it left out";
  const DetectorWindow& w2 = t.windows[2];
  EXPECT_EQ(w2.begin, 7500);
  EXPECT_EQ(w2.iterations, 1);
  EXPECT_DOUBLE_EQ(w2.mean[col("seeker_approach")], 0.5);
  const std::vector<std::string> lines = t.lines();
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[0].rfind("window (M agent-steps)", 0), 0u) << lines[0];
  EXPECT_EQ(lines[3].rfind("0.0075-0.0100 (to 0.00800)", 0), 0u) << lines[3];
  EXPECT_NE(lines[2].find(" -"), std::string::npos) << "no seeker_approach in that window: " << lines[2];
  EXPECT_NE(lines[1].find("-2.00"), std::string::npos) << lines[1];
  EXPECT_THROW(detector_windows(read_metrics_jsonl(text), 0), std::invalid_argument);
}

// Rows that finished no episode (or do not say) count as iterations and add no statistic; a damaged
// agent_steps (beyond any run) is skipped rather than overflowing.
TEST(Stages, DetectorWindowsSkipRowsWithoutEpisodesAndDamagedCounts) {
  const std::string text =
      "{\"iteration\": 1, \"agent_steps\": 100, \"episodes\": 0, \"hider_reward\": 50}\n"
      "{\"iteration\": 2, \"agent_steps\": 200, \"hider_reward\": 60}\n"
      "{\"iteration\": 3, \"agent_steps\": 300, \"episodes\": 4, \"hider_reward\": 2}\n"
      "{\"iteration\": 4, \"agent_steps\": 1e19, \"episodes\": 4, \"hider_reward\": 9}\n";
  const DetectorTable t = detector_windows(read_metrics_jsonl(text), 1000);
  ASSERT_EQ(t.windows.size(), 1u);
  EXPECT_EQ(t.windows[0].iterations, 3);
  EXPECT_EQ(t.windows[0].episodes, 4);
  EXPECT_DOUBLE_EQ(t.windows[0].mean[0], 2.0);
}

// Every column reads a key that metrics.jsonl has: an episode statistic, or the return, entropy or door
// count.
TEST(Stages, DetectorColumnsNameMetricsKeys) {
  std::vector<std::string> keys = {"hider_reward", "entropy", "num_doors"};
#define HNS_STAGES_TEST_KEY(name, doc) keys.push_back(#name);
  HNS_EPISODE_STATS(HNS_STAGES_TEST_KEY)
#undef HNS_STAGES_TEST_KEY
  auto known = [&](const char* k) { return std::find(keys.begin(), keys.end(), k) != keys.end(); };
  for (const DetectorColumn& c : DetectorTable::columns()) {
    EXPECT_TRUE(known(c.key)) << c.key;
    if (c.denominator != nullptr) {
      EXPECT_TRUE(known(c.denominator)) << c.denominator;
    }
  }
}

}  // namespace
}  // namespace hns::replay
