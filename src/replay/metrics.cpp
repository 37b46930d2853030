#include "replay/metrics.hpp"

#include <nlohmann/json.hpp>

namespace hns::replay {

namespace {

bool is_record(const nlohmann::json& row) {
  return !row.is_discarded() && row.is_object() && row.contains("iteration") &&
         row["iteration"].is_number_integer() && row["iteration"].get<int64_t>() >= 1 &&
         row.contains("agent_steps") && row["agent_steps"].is_number();
}

}  // namespace

bool json_nesting_within(std::string_view text, int max_depth) {
  int depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') {
        ++i;  // the escaped character, whatever it is
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth) return false;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return true;
}

bool is_iteration_record(std::string_view line) {
  return json_nesting_within(line) && is_record(nlohmann::json::parse(line, nullptr, false));
}

MetricsRows read_metrics_jsonl(std::string_view text) {
  nlohmann::json rows = nlohmann::json::array();
  size_t number = 0;
  while (!text.empty()) {
    const size_t end = text.find('\n');
    const std::string_view line = text.substr(0, end);
    text = end == std::string_view::npos ? std::string_view() : text.substr(end + 1);
    ++number;
    if (line.empty()) continue;
    nlohmann::json row =
        json_nesting_within(line) ? nlohmann::json::parse(line, nullptr, false) : nlohmann::json();
    if (!is_record(row)) {
      throw MetricsError(number,
                         "is not an iteration record (a JSON object with iteration, a whole number >= 1, and "
                         "agent_steps)");
    }
    rows.push_back(std::move(row));
  }
  return MetricsRows{rows.dump(), rows.size()};
}

}  // namespace hns::replay
