// `hns replay`: turns a trajectory file into one self-contained HTML page that plays the episodes.
//
//   hns replay FILE --html OUT.html [--title TEXT]
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "cli.hpp"
#include "replay/trajectory.hpp"
#include "replay_html.hpp"

namespace hns::tools {

using namespace hns::replay;  // trajectory files, recording, metrics rows
namespace {

struct ReplayOptions {
  std::string file;
  std::string html;
  std::string title;
};

int run_replay(const ReplayOptions& opt) {
  check_output_path("--html", opt.html, {opt.file});
  // The whole file is checked here, so the page never has to show a half-read trajectory.
  std::string bytes;
  TrajectoryFile trajectory;
  try {
    bytes = read_file_bytes(opt.file);
  } catch (const TrajectoryError& e) {
    std::fprintf(stderr, "hns replay: %s\n", e.what());
    return 2;
  }
  try {
    trajectory = decode_trajectory(bytes);
  } catch (const TrajectoryError& e) {
    std::fprintf(stderr, "hns replay: bad trajectory file %s: %s\n", opt.file.c_str(), e.what());
    return 2;
  }
  for (const std::string& w : trajectory.warnings)
    std::fprintf(stderr, "hns replay: warning: %s: %s\n", opt.file.c_str(), w.c_str());
  if (trajectory.episodes.empty()) {
    std::fprintf(stderr, "hns replay: bad trajectory file %s: it holds no episodes\n", opt.file.c_str());
    return 2;
  }
  const std::string title =
      opt.title.empty() ? std::filesystem::path(opt.file).filename().string() : opt.title;
  const std::string page = render_replay_html(bytes, title);
  write_atomically(opt.html, page);
  int frames = 0;
  for (const TrajectoryEpisode& ep : trajectory.episodes) frames += ep.frames;
  std::printf("hns replay: wrote %s (%zu episode%s, %d frames, %.1f KB); open it in a browser\n",
              opt.html.c_str(), trajectory.episodes.size(), trajectory.episodes.size() == 1 ? "" : "s",
              frames, page.size() / 1024.0);
  return 0;
}

}  // namespace

void add_replay_command(CLI::App& app, std::vector<Command>& commands) {
  auto opt = std::make_shared<ReplayOptions>();
  CLI::App* cmd = app.add_subcommand("replay", "Write a self-contained HTML replay of a trajectory file");
  cmd->add_option("file", opt->file, "Trajectory file written by `hns play`")->required();
  cmd->add_option("--html", opt->html, "HTML page to write")->required();
  cmd->add_option("--title", opt->title, "Title shown in the page (default: the file name)");
  commands.push_back({cmd, [opt] { return run_replay(*opt); }});
}

}  // namespace hns::tools
