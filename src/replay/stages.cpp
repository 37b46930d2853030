#include "replay/stages.hpp"

#include "replay/metrics.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <limits>
#include <optional>
#include <stdexcept>

namespace hns::replay {
namespace {

// value = sum(numerator x episodes) / sum(denominator x episodes) over the window; no denominator: the
// mean over the window's episodes. Thresholds: docs/training.md "Stages" says where each comes from.
struct Rule {
  const char* name;
  const char* numerator;
  const char* denominator;  // nullptr: per episode
  double threshold;
  const char* criterion;
};

constexpr Rule kChasing{"running and chasing", "seeker_approach", nullptr, 0.25,
                        "seeker_approach >= 0.25 m/s (seekers run at their nearest hider)"};
constexpr Rule kBoxSurfing{"box surfing", "box_surf", nullptr, 0.1,
                           "box_surf >= 0.1 (a seeker rides a sliding box in 1 episode of 10)"};
constexpr Rule kRampUse{
    "ramp use", "seeker_high_seen", nullptr, 0.2,
    "seeker_high_seen >= 0.2 (in 1 episode of 5 a seeker sees a hider from above a wall)"};

const std::vector<Rule>& rules_of(const std::string& scene) {
  static const std::vector<Rule> quadrant = {
      kChasing,
      {"fort building", "num_door_sealed_prep", "num_doors", 0.5,
       "num_door_sealed_prep / num_doors >= 0.5 (half the doors sealed by locked boxes when prep ends)"},
      kRampUse,
      {"ramp defence", "ramp_in_room_prep", nullptr, 0.5,
       "ramp_in_room_prep >= 0.5 (the ramp is in the room when prep ends in half the episodes)"},
      kBoxSurfing,
  };
  static const std::vector<Rule> full = {
      kChasing,
      {"fort building", "num_box_lock_prep", nullptr, 2.0,
       "num_box_lock_prep >= 2 (boxes locked when prep ends)"},
      kRampUse,
      {"ramp defence", "num_ramp_lock_prep", nullptr, 1.0,
       "num_ramp_lock_prep >= 1 (ramps locked when prep ends)"},
      kBoxSurfing,
  };
  static const std::vector<Rule> none;
  return scene == "quadrant" ? quadrant : scene == "full" ? full : none;
}

double number(const nlohmann::json& row, const char* key) {
  const auto it = row.find(key);
  return it != row.end() && it->is_number() ? it->get<double>() : std::numeric_limits<double>::quiet_NaN();
}

// Counts (iterations, agent-steps) above this are taken as this: no run gets there, a damaged metrics file
// might, and the int64 arithmetic on them must not overflow.
constexpr double kMaxCount = 4611686018427387904.0;  // 2^62

int64_t count_of(double v) {
  return v >= 0 ? int64_t(std::min(v, kMaxCount)) : 0;  // NaN and negative: 0
}

// A row's statistic `key` (over `denominator`, or per episode) weighted by the row's episodes e: {e, key x e,
// denominator x e}, or nothing where the row lacks either or ended no episode (it would add nothing).
std::optional<std::array<double, 3>> weighted(const nlohmann::json& row, double e, const char* key,
                                              const char* denominator) {
  const double a = number(row, key);
  const double b = denominator ? number(row, denominator) : 1.0;
  if (!(e > 0) || !std::isfinite(a) || !std::isfinite(b)) return std::nullopt;
  return std::array<double, 3>{e, a * e, b * e};
}

// "16.6M", "512k", "900".
std::string short_count(double v) {
  char buf[32];
  if (v >= 1e6) {
    std::snprintf(buf, sizeof buf, "%.1fM", v / 1e6);
  } else if (v >= 1e4) {
    std::snprintf(buf, sizeof buf, "%.0fk", v / 1e3);
  } else {
    std::snprintf(buf, sizeof buf, "%.0f", v);
  }
  return buf;
}

}  // namespace

// Every stage's sliding window over the rows added so far: the fewest whole rows back from the latest
// holding kStageWindowEpisodes episodes that have the statistics its criterion reads.
struct StageWindows {
  struct Window {
    Rule rule;
    std::deque<std::array<double, 3>> rows;  // episodes, numerator x episodes, denominator x episodes
    double ep = 0, num = 0, den = 0;
    double value = std::numeric_limits<double>::quiet_NaN();
  };
  std::vector<Window> windows;
  std::vector<StageTrack> stages;  // names, criteria, first appearances (no history)
  int64_t rows = 0, episodes = 0;

  explicit StageWindows(const std::string& scene) {
    for (const Rule& rule : rules_of(scene)) {
      windows.push_back(Window{rule, {}, 0, 0, 0, std::numeric_limits<double>::quiet_NaN()});
      StageTrack t;
      t.name = rule.name;
      t.criterion = rule.criterion;
      t.threshold = rule.threshold;
      stages.push_back(std::move(t));
    }
  }

  // Adds the next row; returns the stages first met at it.
  std::vector<int> add(const nlohmann::json& row) {
    std::vector<int> reached;
    const double e = number(row, "episodes");
    episodes += count_of(e);
    for (size_t k = 0; k < windows.size(); ++k) {
      Window& w = windows[k];
      // Rows without the statistics stay out of the window.
      if (const auto r = weighted(row, e, w.rule.numerator, w.rule.denominator)) {
        w.rows.push_back(*r);
        w.ep += (*r)[0], w.num += (*r)[1], w.den += (*r)[2];
      }
      while (w.rows.size() > 1 && w.ep - w.rows.front()[0] >= kStageWindowEpisodes) {
        w.ep -= w.rows.front()[0], w.num -= w.rows.front()[1], w.den -= w.rows.front()[2];
        w.rows.pop_front();
      }
      w.value = w.ep >= kStageWindowEpisodes && w.den > 0 ? w.num / w.den
                                                          : std::numeric_limits<double>::quiet_NaN();
      StageTrack& t = stages[k];
      if (w.value >= w.rule.threshold && t.first_row < 0) {
        t.first_row = rows;
        t.first_iteration = count_of(number(row, "iteration"));
        t.first_agent_steps = count_of(number(row, "agent_steps"));
        t.first_episodes = episodes;
        reached.push_back(int(k));
      }
    }
    ++rows;
    return reached;
  }
};

StageTracker::StageTracker(const std::string& scene) : w_(std::make_unique<StageWindows>(scene)) {}
StageTracker::~StageTracker() = default;

std::vector<int> StageTracker::add(std::string_view row) {
  const nlohmann::json j =
      json_nesting_within(row) ? nlohmann::json::parse(row, nullptr, false) : nlohmann::json();
  return w_->add(j.is_object() ? j : nlohmann::json::object());
}

const std::vector<StageTrack>& StageTracker::stages() const {
  return w_->stages;
}

double StageTracker::value(int stage) const {
  return w_->windows[size_t(stage)].value;
}

StageReport detect_stages(const MetricsRows& rows, const std::string& scene) {
  const nlohmann::json all = nlohmann::json::parse(rows.json);
  StageWindows w(scene);
  std::vector<std::vector<double>> values(w.windows.size());
  for (const nlohmann::json& row : all) {
    w.add(row);
    for (size_t k = 0; k < w.windows.size(); ++k) values[k].push_back(w.windows[k].value);
  }
  StageReport report;
  report.scene = scene;
  report.stages = std::move(w.stages);
  for (size_t k = 0; k < report.stages.size(); ++k) {
    StageTrack& t = report.stages[k];
    t.value = std::move(values[k]);
    t.on.resize(t.value.size());
    for (size_t i = 0; i < t.value.size(); ++i) t.on[i] = t.value[i] >= t.threshold ? 1 : 0;
  }
  return report;
}

const std::vector<DetectorColumn>& DetectorTable::columns() {
  static const std::vector<DetectorColumn> cols = {
      {"hider_ret", "hider_reward", nullptr},
      {"approach", "seeker_approach", nullptr},
      {"in_room", "hiders_in_room_prep", nullptr},
      {"screened", "hiders_screened_prep", nullptr},
      {"seen", "hider_seen_frac", nullptr},
      {"blocked", "num_door_blocked_prep", "num_doors"},
      {"sealed", "num_door_sealed_prep", "num_doors"},
      {"box_lock", "num_box_lock_prep", nullptr},
      {"ramp_lock", "num_ramp_lock_prep", nullptr},
      {"high", "seeker_high", nullptr},
      {"high_seen", "seeker_high_seen", nullptr},
      {"ramp_room", "ramp_in_room_prep", nullptr},
      {"box_surf", "box_surf", nullptr},
      {"entropy", "entropy", nullptr},
  };
  return cols;
}

DetectorTable detector_windows(const MetricsRows& rows, int64_t window_agent_steps) {
  if (window_agent_steps < 1) throw std::invalid_argument("the window must hold at least one agent-step");
  const std::vector<DetectorColumn>& cols = DetectorTable::columns();
  const nlohmann::json all = nlohmann::json::parse(rows.json);
  DetectorTable table;
  table.window = window_agent_steps;
  std::vector<double> num, den;  // the current window's sums per column
  auto finish = [&] {
    DetectorWindow& w = table.windows.back();
    for (size_t c = 0; c < cols.size(); ++c)
      w.mean.push_back(den[c] > 0 ? num[c] / den[c] : std::numeric_limits<double>::quiet_NaN());
  };
  for (const nlohmann::json& row : all) {
    const double steps = number(row, "agent_steps");
    if (!(steps >= 1) || steps >= kMaxCount) continue;
    const int64_t last = count_of(steps);
    const int64_t begin = (last - 1) / window_agent_steps * window_agent_steps;
    // A new window at every change (rows of one run only go forwards; a file of two runs' rows pasted
    // together would show a window twice).
    if (table.windows.empty() || table.windows.back().begin != begin) {
      if (!table.windows.empty()) finish();
      table.windows.push_back({begin, begin + window_agent_steps, last, 0, 0, {}});
      num.assign(cols.size(), 0.0);
      den.assign(cols.size(), 0.0);
    }
    DetectorWindow& w = table.windows.back();
    w.last_agent_steps = last;
    ++w.iterations;
    const double e = number(row, "episodes");
    if (e > 0) w.episodes += e;
    for (size_t c = 0; c < cols.size(); ++c) {
      if (const auto r = weighted(row, e, cols[c].key, cols[c].denominator))
        num[c] += (*r)[1], den[c] += (*r)[2];
    }
  }
  if (!table.windows.empty()) finish();
  return table;
}

std::vector<std::string> DetectorTable::lines() const {
  const std::vector<DetectorColumn>& cols = columns();
  // Millions of agent-steps with as many decimals as the window needs to be exact (up to 6), the last row's
  // with one more.
  int decimals = 0;
  for (int64_t unit = 1000000; decimals < 6 && window % unit != 0; unit /= 10) ++decimals;
  auto millions = [](int64_t steps, int d) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.*f", d, double(steps) / 1e6);
    return std::string(buf);
  };
  std::vector<std::string> labels;
  size_t width = std::strlen("window (M agent-steps)");
  for (const DetectorWindow& w : windows) {
    labels.push_back(millions(w.begin, decimals) + "-" + millions(w.end, decimals) + " (to " +
                     millions(w.last_agent_steps, std::min(decimals + 1, 6)) + ")");
    width = std::max(width, labels.back().size());
  }
  auto pad = [width](std::string text) {
    text.resize(width, ' ');
    return text;
  };
  std::vector<std::string> out;
  std::string head = pad("window (M agent-steps)") + "  iterations   episodes";
  for (const DetectorColumn& c : cols) {
    char buf[32];
    std::snprintf(buf, sizeof buf, " %9s", c.header);
    head += buf;
  }
  out.push_back(head);
  for (size_t k = 0; k < windows.size(); ++k) {
    const DetectorWindow& w = windows[k];
    char buf[64];
    std::snprintf(buf, sizeof buf, "  %10lld %10.0f", static_cast<long long>(w.iterations), w.episodes);
    std::string line = pad(labels[k]) + buf;
    for (size_t c = 0; c < cols.size(); ++c) {
      const double v = w.mean[c];
      if (!std::isfinite(v)) {
        line += "         -";
      } else {
        std::snprintf(buf, sizeof buf, c == 0 ? " %+9.2f" : " %9.3f", v);
        line += buf;
      }
    }
    out.push_back(line);
  }
  return out;
}

std::string StageTrack::reached_text() const {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s: from iteration %lld (%s agent-steps, %s episodes)", name.c_str(),
                static_cast<long long>(first_iteration), short_count(double(first_agent_steps)).c_str(),
                short_count(double(first_episodes)).c_str());
  return buf;
}

std::string StageReport::to_json() const {
  nlohmann::json j;
  j["scene"] = scene;
  j["window_episodes"] = kStageWindowEpisodes;
  j["stages"] = nlohmann::json::array();
  for (const StageTrack& t : stages) {
    nlohmann::json s;
    s["name"] = t.name;
    s["criterion"] = t.criterion;
    s["threshold"] = t.threshold;
    nlohmann::json values = nlohmann::json::array();
    for (double v : t.value) values.push_back(std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr));
    s["value"] = std::move(values);
    std::string on(t.on.size(), '0');
    for (size_t i = 0; i < t.on.size(); ++i) on[i] = t.on[i] ? '1' : '0';
    s["on"] = on;
    s["first_row"] = t.first_row;
    s["first_iteration"] = t.first_iteration;
    s["first_agent_steps"] = t.first_agent_steps;
    s["first_episodes"] = t.first_episodes;
    j["stages"].push_back(std::move(s));
  }
  return j.dump();
}

std::vector<std::string> StageReport::summary() const {
  std::vector<std::string> lines;
  for (const StageTrack& t : stages) {
    if (t.first_row >= 0) {
      lines.push_back(t.reached_text());
      continue;
    }
    double last = std::numeric_limits<double>::quiet_NaN();
    for (size_t i = t.value.size(); i-- > 0;) {
      if (std::isfinite(t.value[i])) {
        last = t.value[i];
        break;
      }
    }
    char buf[256];
    if (std::isfinite(last)) {
      std::snprintf(buf, sizeof buf, "%s: not reached (last window %.3g, needs >= %g)", t.name.c_str(), last,
                    t.threshold);
    } else {
      std::snprintf(buf, sizeof buf, "%s: not reached (fewer than %.0f episodes with its statistics)",
                    t.name.c_str(), kStageWindowEpisodes);
    }
    lines.emplace_back(buf);
  }
  return lines;
}

}  // namespace hns::replay
