#include "report_html.hpp"

#include <nlohmann/json.hpp>

#include <stdexcept>

#include "replay_html.hpp"

namespace hns::tools {

// Generated from tools/report_viewer.html by cmake/HnsEmbedText.cmake.
extern const char kReportViewerHtml[];

namespace {

// JSON inside <script type="application/json">: "</" would end the script element early.
std::string script_safe(const std::string& json) {
  std::string out;
  out.reserve(json.size());
  for (size_t i = 0; i < json.size(); ++i) {
    if (json[i] == '<' && i + 1 < json.size() && json[i + 1] == '/') {
      out += "<\\/";
      ++i;
    } else {
      out += json[i];
    }
  }
  return out;
}

}  // namespace

std::string render_report_html(const ReportInputs& in) {
  std::string page(kReportViewerHtml);
  // Data slots first (their values cannot contain the other slots once escaped), the title last.
  const std::string replay =
      in.replay_html.empty()
          ? std::string(
                "<p>No recording yet: <code>hns train</code> records two episodes with every "
                "checkpoint into the run folder's <code>replay.traj</code>.</p>")
          : "<iframe title=\"replay\" srcdoc=\"" + html_escape(in.replay_html) + "\"></iframe>";
  if (replace_all(page, "@HNS_METRICS_JSON@", script_safe(in.metrics_json)) != 1 ||
      replace_all(page, "@HNS_CONFIG_JSON@", script_safe(in.config_json)) != 1 ||
      replace_all(page, "@HNS_STAGES_JSON@", script_safe(in.stages_json)) != 1 ||
      replace_all(page, "@HNS_REPLAY@", replay) != 1) {
    throw std::logic_error("report_viewer.html must hold each data slot exactly once");
  }
  replace_all(page, "@HNS_TITLE@", html_escape(in.title));
  return page;
}

}  // namespace hns::tools
