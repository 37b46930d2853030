// The training report page: tools/report_viewer.html (embedded at build time) with a run's metrics, its
// config and, when the run recorded one, a replay page of its latest policy inlined. Needs no network.
#pragma once

#include <string>

namespace hns::tools {

struct ReportInputs {
  std::string title;
  std::string metrics_json;  // a JSON array of the iteration objects
  std::string config_json;   // the run's config object
  std::string stages_json;   // replay::StageReport::to_json()
  std::string replay_html;   // a whole replay page, or "" when the run has no recording
};

std::string render_report_html(const ReportInputs& in);

}  // namespace hns::tools
