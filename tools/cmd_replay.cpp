// `hns replay`: turns a trajectory file into one self-contained HTML page that plays the episodes, and/or an
// animated GIF of them (top-down pictures, replay/render.hpp).
//
//   hns replay FILE [--html OUT.html] [--title TEXT] [--gif OUT.gif] [--size PX] [--every K] [--speed X]
//              [--episode N]
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "cli.hpp"
#include "replay/render.hpp"
#include "replay/trajectory.hpp"
#include "replay_html.hpp"

namespace hns::tools {

using namespace hns::replay;  // trajectory files, recording, metrics rows
namespace {

struct ReplayOptions {
  std::string file;
  std::string html;
  std::string title;
  std::string gif;
  GifOptions gif_options;
  int episode = -1;  // -1: every episode
};

int run_replay(const ReplayOptions& opt) {
  if (opt.html.empty() && opt.gif.empty()) {
    std::fprintf(stderr, "hns replay: say what to write: --html PAGE, --gif ANIMATION or both\n");
    return 2;
  }
  if (!opt.html.empty()) check_output_path("--html", opt.html, {opt.file});
  if (!opt.gif.empty()) check_output_path("--gif", opt.gif, {opt.file, opt.html});
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
  const int num_episodes = static_cast<int>(trajectory.episodes.size());
  if (opt.episode >= num_episodes) {
    std::fprintf(stderr, "hns replay: --episode %d: %s holds episodes 0 to %d\n", opt.episode,
                 opt.file.c_str(), num_episodes - 1);
    return 2;
  }
  if (!opt.html.empty()) {
    const std::string title =
        opt.title.empty() ? std::filesystem::path(opt.file).filename().string() : opt.title;
    const std::string page = render_replay_html(bytes, title);
    write_atomically(opt.html, page);
    int frames = 0;
    for (const TrajectoryEpisode& ep : trajectory.episodes) frames += ep.frames;
    std::printf("hns replay: wrote %s (%s, %d frames, %.1f KB); open it in a browser\n", opt.html.c_str(),
                count_text(num_episodes, "episode").c_str(), frames, page.size() / 1024.0);
  }
  if (!opt.gif.empty()) {
    std::vector<const TrajectoryEpisode*> episodes;
    for (int e = 0; e < num_episodes; ++e)
      if (opt.episode < 0 || e == opt.episode) episodes.push_back(&trajectory.episodes[size_t(e)]);
    int pictures = 0;
    const std::string gif = encode_gif(episodes, opt.gif_options, &pictures);
    write_atomically(opt.gif, gif);
    std::printf("hns replay: wrote %s (%s, %d pictures of %d x %d px, %.1f KB)\n", opt.gif.c_str(),
                count_text(static_cast<int>(episodes.size()), "episode").c_str(), pictures,
                opt.gif_options.size, opt.gif_options.size, gif.size() / 1024.0);
  }
  return 0;
}

}  // namespace

void add_replay_command(CLI::App& app, std::vector<Command>& commands) {
  auto opt = std::make_shared<ReplayOptions>();
  CLI::App* cmd = app.add_subcommand(
      "replay", "Write a self-contained HTML replay and/or an animated GIF of a trajectory file");
  cmd->add_option("file", opt->file, "Trajectory file written by `hns play`")->required();
  cmd->add_option("--html", opt->html, "HTML page to write");
  cmd->add_option("--title", opt->title, "Title shown in the page (default: the file name)");
  cmd->add_option("--gif", opt->gif,
                  "Animated GIF to write: top-down pictures of the episodes, one after another");
  cmd->add_option("--size", opt->gif_options.size, "GIF: pixels per side")
      ->check(CLI::Range(64, 4096))
      ->capture_default_str();
  cmd->add_option("--every", opt->gif_options.every, "GIF: draw every k-th frame (and each episode's last)")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd->add_option("--speed", opt->gif_options.speed, "GIF: playback speed, 1 = real time (0.075 s a step)")
      ->check(CLI::Range(0.01, 100.0))
      ->capture_default_str();
  cmd->add_option("--episode", opt->episode, "GIF: only this episode (0-based; default: every one)")
      ->check(CLI::Range(0, 1000000));
  commands.push_back({cmd, [opt] { return run_replay(*opt); }});
}

}  // namespace hns::tools
