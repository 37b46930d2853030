#include "report_html.hpp"

#include <nlohmann/json.hpp>

#include <stdexcept>

#include "replay_html.hpp"

namespace hns::tools {

// Generated from tools/report_viewer.html by cmake/HnsEmbedText.cmake.
extern const char kReportViewerHtml[];

namespace {

// JSON inside <script type="application/json">: every "<" is written as the JSON escape \u003c (it can only
// occur inside a string), so no text of the data ("</script>", "<!--<script>") can end or change the script
// element.
std::string script_safe(const std::string& json) {
  std::string out;
  out.reserve(json.size());
  for (char c : json) {
    if (c == '<') {
      out += "\\u003c";
    } else {
      out += c;
    }
  }
  return out;
}

}  // namespace

std::string render_report_html(const ReportInputs& in) {
  const std::string replay =
      in.replay_html.empty()
          ? std::string(
                "<p>No recording yet: <code>hns train</code> records two episodes with every "
                "checkpoint into the run folder's <code>replay.traj</code>.</p>")
          : "<iframe title=\"replay\" sandbox=\"allow-scripts\" srcdoc=\"" + html_escape(in.replay_html) +
                "\"></iframe>";
  return fill_template(kReportViewerHtml, {{"@HNS_METRICS_JSON@", script_safe(in.metrics_json)},
                                           {"@HNS_CONFIG_JSON@", script_safe(in.config_json)},
                                           {"@HNS_STAGES_JSON@", script_safe(in.stages_json)},
                                           {"@HNS_REPLAY@", replay},
                                           {"@HNS_TITLE@", html_escape(in.title), false}});
}

}  // namespace hns::tools
