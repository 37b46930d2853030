// metrics.jsonl of a training run (docs/training.md): one JSON object per iteration, appended by `hns train`.
// Read by `hns report` and by the Python module's hns.read_metrics.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>

namespace hns::replay {

// A line of metrics.jsonl that is not an iteration record.
struct MetricsError : std::runtime_error {
  MetricsError(size_t line_number, const std::string& what) : std::runtime_error(what), line(line_number) {}
  size_t line;  // 1-based
};

struct MetricsRows {
  std::string json;  // "[{...}, ...]"
  size_t rows = 0;
};

// JSON that hns reads from files (metrics rows, trajectory headers, a report's config, eval.json) nests no
// deeper than this: nlohmann::json's parser and printer recurse once per level, so a file nested tens of
// thousands of levels deep would overflow the stack. Deeper text counts as malformed.
inline constexpr int kMaxJsonDepth = 64;
// Whether the arrays and objects of a JSON text nest at most `max_depth` levels (brackets inside strings do
// not count; the text need not be valid JSON otherwise).
bool json_nesting_within(std::string_view text, int max_depth = kMaxJsonDepth);

// Whether one line of metrics.jsonl is an iteration record: a JSON object whose "iteration" is a whole
// number >= 1 and whose "agent_steps" is a number. What hns report reads and hns train --resume keeps.
bool is_iteration_record(std::string_view line);

// The rows of a metrics.jsonl text as one JSON array (blank lines skipped). Throws MetricsError naming the
// first line that is not an iteration record.
MetricsRows read_metrics_jsonl(std::string_view text);

}  // namespace hns::replay
