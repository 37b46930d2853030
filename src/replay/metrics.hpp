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

// The rows of a metrics.jsonl text as one JSON array (blank lines skipped). Throws MetricsError naming the
// first line that is not an iteration record: a JSON object with "iteration" and "agent_steps" numbers.
MetricsRows read_metrics_jsonl(std::string_view text);

}  // namespace hns::replay
