// `hns report`: a training run folder (metrics.jsonl, config.json, replay.traj) as one self-contained HTML
// page with curves, the band of the paper's stages detected in them and a replay of the latest checkpoint's
// policy; prints when each stage first appeared, and with --windows the stage detectors' means per window of
// agent-steps (a long run's log).
//
//   hns report RUN_DIR [--html OUT.html] [--title TEXT] [--windows M]
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "cli.hpp"
#include "ppo/atomic_file.hpp"
#include "replay/metrics.hpp"
#include "replay/stages.hpp"
#include "replay/trajectory.hpp"
#include "replay_html.hpp"
#include "report_html.hpp"

namespace hns::tools {

using namespace hns::replay;  // trajectory files, recording, metrics rows
namespace {

namespace fs = std::filesystem;

struct ReportOptions {
  std::string dir;
  std::string html;
  std::string title;
  double windows = 0;  // millions of agent-steps per window of the detector table; 0: no table
};

int run_report(const ReportOptions& opt) {
  const fs::path dir(opt.dir);
  const fs::path metrics_path = dir / "metrics.jsonl";
  if (opt.html.empty() && opt.windows == 0) {
    std::fprintf(stderr,
                 "hns report: nothing to do: give --html FILE (the report page), --windows M (the "
                 "detectors per M million agent-steps) or both\n");
    return 2;
  }
  if (!opt.html.empty())
    check_output_path("--html", opt.html,
                      {metrics_path.string(), (dir / "config.json").string(), (dir / "replay.traj").string(),
                       (dir / "checkpoint.bin").string()});
  std::string text;
  try {
    text = ppo::read_regular_file(metrics_path.string(), ppo::kMaxMetricsBytes, "");
  } catch (const ppo::FileError& e) {
    std::fprintf(stderr, "hns report: %s\n", e.what());
    return 2;
  } catch (const std::exception&) {
    std::fprintf(stderr, "hns report: %s cannot be read (is %s a run folder of hns train?)\n",
                 metrics_path.string().c_str(), opt.dir.c_str());
    return 2;
  }
  MetricsRows metrics;
  try {
    metrics = read_metrics_jsonl(text);
  } catch (const MetricsError& e) {
    std::fprintf(stderr, "hns report: %s:%zu %s\n", metrics_path.string().c_str(), e.line, e.what());
    return 2;
  }
  nlohmann::json config = nlohmann::json::object();
  std::error_code ec;
  if (fs::exists(dir / "config.json", ec)) {
    std::string cf;
    try {
      cf = ppo::read_regular_file((dir / "config.json").string(), ppo::kMaxConfigBytes, "");
    } catch (const std::exception& e) {
      std::fprintf(stderr, "hns report: %s\n", e.what());
      return 2;
    }
    config = replay::json_nesting_within(cf) ? nlohmann::json::parse(cf, nullptr, false) : nlohmann::json();
    if (config.is_discarded() || !config.is_object()) {
      std::fprintf(stderr, "hns report: %s is not a JSON object\n", (dir / "config.json").string().c_str());
      return 2;
    }
  }
  // The stages need both teams: a run whose config sets one of them to 0 (a count-based baseline) has none.
  auto no_team = [&config](const char* key) {
    return config.contains(key) && config[key].is_number_integer() && config[key].get<int>() == 0;
  };
  const std::string scene =
      config.contains("scene") && config["scene"].is_string() && !no_team("hiders") && !no_team("seekers")
          ? config["scene"].get<std::string>()
          : "";
  const StageReport stages = detect_stages(metrics, scene);
  if (!opt.html.empty()) {
    std::string replay;
    const fs::path traj = dir / "replay.traj";
    if (fs::exists(traj)) {
      try {
        const std::string bytes = read_file_bytes(traj.string());
        const TrajectoryFile file = decode_trajectory(bytes);
        if (!file.episodes.empty()) replay = render_replay_html(bytes, "replay: " + file.policy);
      } catch (const TrajectoryError& e) {
        std::fprintf(stderr, "hns report: warning: %s is unreadable, the report has no replay: %s\n",
                     traj.string().c_str(), e.what());
      }
    }
    ReportInputs inputs;
    inputs.title = opt.title.empty() ? "hns training report: " + opt.dir : opt.title;
    inputs.metrics_json = metrics.json;
    inputs.config_json = config.dump();
    inputs.stages_json = stages.to_json();
    inputs.replay_html = replay;
    const std::string page = render_report_html(inputs);
    write_atomically(opt.html, page);
    std::printf("hns report: wrote %s (%zu iterations%s, %.1f KB); open it in a browser\n", opt.html.c_str(),
                metrics.rows, replay.empty() ? ", no replay" : ", with a replay", page.size() / 1024.0);
  }
  if (!stages.stages.empty()) {
    std::printf("stages (docs/training.md; each over windows of %.0f episodes):\n", kStageWindowEpisodes);
    for (const std::string& line : stages.summary()) std::printf("  %s\n", line.c_str());
  }
  if (opt.windows > 0) {
    const DetectorTable table =
        detector_windows(metrics, static_cast<int64_t>(std::llround(opt.windows * 1e6)));
    std::printf(
        "detectors per %g M agent-steps (episode-weighted means; blocked and sealed per door; "
        "docs/training.md \"Stages\"):\n",
        opt.windows);
    for (const std::string& line : table.lines()) std::printf("%s\n", line.c_str());
  }
  return 0;
}

}  // namespace

void add_report_command(CLI::App& app, std::vector<Command>& commands) {
  auto opt = std::make_shared<ReportOptions>();
  CLI::App* cmd = app.add_subcommand(
      "report",
      "A training run's self-contained HTML report, and its stage detectors per window of agent-steps");
  cmd->add_option("run_dir", opt->dir, "Run folder written by `hns train`")->required();
  CLI::Option* html = cmd->add_option("--html", opt->html, "HTML file to write");
  cmd->add_option("--title", opt->title, "Title shown in the page")->needs(html);
  cmd->add_option("--windows", opt->windows,
                  "Print the stage detectors' means per window of this many million agent-steps")
      ->check(CLI::Range(0.001, 1e6));
  commands.push_back({cmd, [opt] { return run_report(*opt); }});
}

}  // namespace hns::tools
