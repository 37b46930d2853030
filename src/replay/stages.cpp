#include "replay/stages.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <limits>

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
      {"box surfing", "box_surf", nullptr, 0.1,
       "box_surf >= 0.1 (a seeker rides a sliding box in 1 episode of 10)"},
  };
  static const std::vector<Rule> none;
  return scene == "quadrant" ? quadrant : scene == "full" ? full : none;
}

double number(const nlohmann::json& row, const char* key) {
  const auto it = row.find(key);
  return it != row.end() && it->is_number() ? it->get<double>() : std::numeric_limits<double>::quiet_NaN();
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

StageReport detect_stages(const MetricsRows& rows, const std::string& scene) {
  StageReport report;
  report.scene = scene;
  const nlohmann::json all = nlohmann::json::parse(rows.json);
  const size_t n = all.size();
  // Episodes finished by the end of each row.
  std::vector<int64_t> done(n);
  int64_t total = 0;
  for (size_t i = 0; i < n; ++i) {
    const double e = number(all[i], "episodes");
    total += std::isfinite(e) ? int64_t(e) : 0;
    done[i] = total;
  }
  for (const Rule& rule : rules_of(scene)) {
    StageTrack t;
    t.name = rule.name;
    t.criterion = rule.criterion;
    t.threshold = rule.threshold;
    t.value.assign(n, std::numeric_limits<double>::quiet_NaN());
    t.on.assign(n, 0);
    // Per row: episodes that count, and their sums of numerator and denominator.
    std::vector<double> ep(n, 0.0), num(n, 0.0), den(n, 0.0);
    for (size_t i = 0; i < n; ++i) {
      const double e = number(all[i], "episodes"), a = number(all[i], rule.numerator);
      const double b = rule.denominator ? number(all[i], rule.denominator) : 1.0;
      if (!(e > 0) || !std::isfinite(a) || !std::isfinite(b)) continue;
      ep[i] = e, num[i] = a * e, den[i] = b * e;
    }
    // Sliding window [lo, i]: the fewest rows back from i holding kStageWindowEpisodes episodes.
    double sum_ep = 0, sum_num = 0, sum_den = 0;
    size_t lo = 0;
    for (size_t i = 0; i < n; ++i) {
      sum_ep += ep[i], sum_num += num[i], sum_den += den[i];
      while (lo < i && sum_ep - ep[lo] >= kStageWindowEpisodes) {
        sum_ep -= ep[lo], sum_num -= num[lo], sum_den -= den[lo];
        ++lo;
      }
      if (sum_ep < kStageWindowEpisodes || !(sum_den > 0)) continue;
      t.value[i] = sum_num / sum_den;
      t.on[i] = t.value[i] >= rule.threshold ? 1 : 0;
      if (t.on[i] && t.first_row < 0) {
        t.first_row = int64_t(i);
        t.first_iteration = int64_t(number(all[i], "iteration"));
        t.first_agent_steps = int64_t(number(all[i], "agent_steps"));
        t.first_episodes = done[i];
      }
    }
    report.stages.push_back(std::move(t));
  }
  return report;
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
    char buf[256];
    if (t.first_row >= 0) {
      std::snprintf(buf, sizeof buf, "%s: from iteration %lld (%s agent-steps, %s episodes)", t.name.c_str(),
                    static_cast<long long>(t.first_iteration),
                    short_count(double(t.first_agent_steps)).c_str(),
                    short_count(double(t.first_episodes)).c_str());
    } else {
      double last = std::numeric_limits<double>::quiet_NaN();
      for (size_t i = t.value.size(); i-- > 0;) {
        if (std::isfinite(t.value[i])) {
          last = t.value[i];
          break;
        }
      }
      if (std::isfinite(last)) {
        std::snprintf(buf, sizeof buf, "%s: not reached (last window %.3g, needs >= %g)", t.name.c_str(),
                      last, t.threshold);
      } else {
        std::snprintf(buf, sizeof buf, "%s: not reached (fewer than %.0f episodes with its statistics)",
                      t.name.c_str(), kStageWindowEpisodes);
      }
    }
    lines.emplace_back(buf);
  }
  return lines;
}

}  // namespace hns::replay
