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

// Whether one line of metrics.jsonl is an iteration record: a JSON object whose "iteration" is a whole
// number >= 1 and whose "agent_steps" is a number. What hns report reads and hns train --resume keeps.
bool is_iteration_record(std::string_view line);

// The rows of a metrics.jsonl text as one JSON array (blank lines skipped). Throws MetricsError naming the
// first line that is not an iteration record.
MetricsRows read_metrics_jsonl(std::string_view text);

}  // namespace hns::replay
