// The paper's stages of emergence, detected in a run's metrics.jsonl (docs/training.md "Stages"): each stage
// is a criterion on the episode statistics (batch::EpisodeStats), evaluated on a sliding window of the last
// kStageWindowEpisodes episodes. Used by `hns report` (the stage band, its table and the printed summary).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "replay/metrics.hpp"

namespace hns::replay {

// A stage's criterion is evaluated on windows of at least this many episodes (whole iterations, back from
// the current one).
inline constexpr double kStageWindowEpisodes = 1000;

struct StageTrack {
  std::string name;       // "fort building"
  std::string criterion;  // "num_door_sealed_prep / num_doors >= 0.5", as shown to the user
  double threshold = 0;
  // Per metrics row: the windowed value (NaN while the window holds fewer than kStageWindowEpisodes
  // episodes with the statistics the criterion needs) and whether it meets the threshold.
  std::vector<double> value;
  std::vector<uint8_t> on;
  // The first row whose window meets the threshold (-1: not reached) and where the run was then.
  int64_t first_row = -1;
  int64_t first_iteration = 0;
  int64_t first_agent_steps = 0;
  int64_t first_episodes = 0;  // episodes the run had finished by then (the paper counts episodes)
  // "fort building: from iteration 812 (16.6M agent-steps, 52k episodes)".
  std::string reached_text() const;
};

struct StageReport {
  std::string scene;
  std::vector<StageTrack> stages;  // in the paper's order; empty for scenes without detectors
  std::string to_json() const;     // {"scene", "window_episodes", "stages": [{name, criterion, ...}]}
  // One line per stage: "fort building: from iteration 812 (16.6M agent-steps, 52k episodes)" or
  // "fort building: not reached (last window 0.03, needs >= 0.5)".
  std::vector<std::string> summary() const;
};

struct StageWindows;  // stages.cpp

// The same detection one metrics row at a time, keeping only the windows (`hns train` announces each stage
// as it first appears, however long the run).
class StageTracker {
 public:
  explicit StageTracker(const std::string& scene);
  ~StageTracker();
  StageTracker(const StageTracker&) = delete;
  StageTracker& operator=(const StageTracker&) = delete;
  // Adds the next line of metrics.jsonl (an object written by IterationMetrics::to_json; anything else counts
  // as a row without statistics); returns the stages (indices into stages()) first met at this row.
  std::vector<int> add(std::string_view row);
  // Names, criteria and first appearances (value and on stay empty).
  const std::vector<StageTrack>& stages() const;
  // The latest window's value of a stage (NaN while its window is short).
  double value(int stage) const;

 private:
  std::unique_ptr<StageWindows> w_;
};

// The stages of `scene` ("quadrant" or "full"; other scenes have none) over the metrics rows. Rows written
// before a statistic existed (older runs, resumed with a newer hns) leave that statistic's windows.
StageReport detect_stages(const MetricsRows& rows, const std::string& scene);

// One window of detector_windows: the rows whose agent_steps lie in (begin, end].
struct DetectorWindow {
  int64_t begin = 0, end = 0;
  int64_t last_agent_steps = 0;  // agent_steps of its last row (below end in a window the run has not filled)
  int64_t iterations = 0;        // its rows
  double episodes = 0;           // episodes its rows finished
  std::vector<double> mean;      // per DetectorTable::columns(); NaN: no row of the window has it
};

// A column of the table: metrics key, and the key it is divided by (the door detectors, per door).
struct DetectorColumn {
  const char* header;       // "sealed"
  const char* key;          // "num_door_sealed_prep"
  const char* denominator;  // "num_doors", or nullptr: per episode
};

struct DetectorTable {
  static const std::vector<DetectorColumn>& columns();
  int64_t window = 1;                   // agent-steps per window
  std::vector<DetectorWindow> windows;  // in the rows' order; windows without rows are left out
  // A header line and one line per window ("-" for NaN), agent-steps in millions.
  std::vector<std::string> lines() const;
};

// The stage detectors' means per window of agent-steps: the log of a long run (`hns report --windows`;
// docs/training.md "Stages"). A row belongs to the window of its last agent-step (a row ending at exactly
// 50 M agent-steps is in 0-50 M). Each column is the mean over the window's rows that have it and finished
// episodes, weighted by their episodes (entropy too, which is per iteration), the door detectors per door
// (the sum of value x episodes over the sum of num_doors x episodes, as the fort criterion). Rows whose
// agent_steps is below 1 or at least 2^62 (a damaged file) are skipped. Throws std::invalid_argument for a
// window below 1 agent-step.
DetectorTable detector_windows(const MetricsRows& rows, int64_t window_agent_steps);

}  // namespace hns::replay
