// The training report page: tools/report_viewer.html (embedded at build time) with a run's metrics, its
// config and, when the run recorded one, a replay page of its latest policy inlined. Needs no network.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>

namespace hns::tools {

// The rows of a metrics.jsonl text as one JSON array (blank lines skipped). Throws MetricsError naming the
// first line that is not an iteration record: a JSON object with "iteration" and "agent_steps" numbers.
struct MetricsError : std::runtime_error {
  MetricsError(size_t line_number, const std::string& what) : std::runtime_error(what), line(line_number) {}
  size_t line;  // 1-based
};
struct MetricsRows {
  std::string json;  // "[{...}, ...]"
  size_t rows = 0;
};
MetricsRows read_metrics_jsonl(std::string_view text);

struct ReportInputs {
  std::string title;
  std::string metrics_json;  // a JSON array of the iteration objects
  std::string config_json;   // the run's config object
  std::string replay_html;   // a whole replay page, or "" when the run has no recording
};

std::string render_report_html(const ReportInputs& in);

}  // namespace hns::tools
