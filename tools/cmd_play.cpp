// `hns play`: records whole episodes into a trajectory file for `hns replay` (docs/trajectory-format.md).
//
//   hns play [--scene NAME (batch::kScenes)] [--random | --checkpoint FILE] [--episodes E] [--seed S]
//   [--envs N]
//            [--threads T] [--hiders H --seekers K --boxes B --ramps R] --out FILE [--gif ANIMATION]
//            [--html PAGE]
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "batch/batch_sim.hpp"
#include "batch/scenes.hpp"
#include "cli.hpp"
#include "ppo/policy.hpp"
#include "replay/play.hpp"
#include "replay/recorder.hpp"
#include "replay/render.hpp"
#include "replay/trajectory.hpp"
#include "replay_html.hpp"

namespace hns::tools {

using namespace hns::replay;  // trajectory files, recording, metrics rows
namespace {

namespace phys = hns::physics;

struct PlayOptions {
  std::string scene;  // default quadrant, or the checkpoint's
  bool random = false;
  std::string checkpoint;
  int episodes = 1;
  std::string seed_text = "1";
  uint64_t seed = 1;  // parsed from seed_text
  int envs = 1;
  int threads = 1;
  std::optional<int> hiders, seekers, boxes, ramps;
  std::string out;
  std::string gif;   // also an animated GIF of the recorded episodes (replay/render.hpp)
  std::string html;  // also the replay page of the recording (as hns replay --html)
};

int run_play(const PlayOptions& opt) {
  std::unique_ptr<ppo::Policy> policy;
  check_output_path("--out", opt.out, {opt.checkpoint});
  if (!opt.gif.empty()) check_output_path("--gif", opt.gif, {opt.checkpoint, opt.out});
  if (!opt.html.empty()) check_output_path("--html", opt.html, {opt.checkpoint, opt.out, opt.gif});
  if (!opt.checkpoint.empty()) {
    try {
      policy = ppo::Policy::from_checkpoint(opt.checkpoint, opt.seed);
    } catch (const std::runtime_error& e) {
      std::fprintf(stderr, "hns play: --checkpoint: %s\n", e.what());
      return 2;
    }
  }
  RecordConfig config;
  try {
    config = play_config(opt.scene, policy.get(),
                         batch::CountOverrides{opt.hiders, opt.seekers, opt.boxes, opt.ramps}, opt.episodes,
                         opt.envs, usable_threads(opt.threads), opt.seed);
  } catch (const phys::ConfigError& e) {
    // The command line's names for the scene.
    std::string what = e.what();
    if (what.rfind("scene = ", 0) == 0) what = "--scene " + what.substr(8);
    throw phys::ConfigError(what);
  }
  check_memory("--envs " + std::to_string(opt.envs), config.game.estimated_bytes());
  const std::string& scene = config.scene;

  std::printf("hns play: scene %s, %d episode%s of %d steps on %d env%s, %s, seed %llu\n", scene.c_str(),
              opt.episodes, opt.episodes == 1 ? "" : "s", config.game.world.horizon, config.game.num_envs,
              config.game.num_envs == 1 ? "" : "s",
              policy ? "actions from the checkpoint's policy" : "random actions",
              static_cast<unsigned long long>(opt.seed));
  std::fflush(stdout);
  TrajectoryFile meta;
  meta.created_by = "hns play";
  meta.policy = policy ? opt.checkpoint : "random";
  TrajectoryWriter writer(opt.out, meta, opt.episodes);
  const RecordSummary summary =
      record_episodes(config, play_actions(policy.get(), opt.seed), [&](const TrajectoryEpisode& ep) {
        writer.add(ep);
        std::printf(
            "  env %d episode %d: %s v %s, %s (%d elongated), %s, %s, returns hiders %+.1f seekers %+.1f\n",
            ep.env, ep.episode, count_text(ep.num_hiders, "hider").c_str(),
            count_text(ep.num_seekers, "seeker").c_str(), count_text(ep.num_boxes, "box", "boxes").c_str(),
            ep.num_elongated, count_text(ep.num_ramps, "ramp").c_str(),
            count_text(ep.frames, "frame").c_str(), ep.hider_return, ep.seeker_return);
        std::fflush(stdout);
      });
  const uint64_t bytes = writer.finish();
  if (summary.discarded > 0) {
    std::printf("  warning: %d episode(s) were cut short by numerical trouble and not recorded\n",
                summary.discarded);
  }
  std::printf("  wrote %s (%.1f KB); view it with: hns replay %s --html replay.html\n", opt.out.c_str(),
              bytes / 1024.0, opt.out.c_str());
  if (!opt.html.empty()) {
    // The page of the recording as written, as hns replay --html makes it.
    const std::string bytes = read_file_bytes(opt.out);
    const std::string page = render_replay_html(bytes, std::filesystem::path(opt.out).filename().string());
    write_atomically(opt.html, page);
    std::printf("  wrote %s (%.1f KB); open it in a browser\n", opt.html.c_str(), page.size() / 1024.0);
  }
  if (!opt.gif.empty()) {
    // The recording as written (so the animation shows exactly the file's episodes).
    const TrajectoryFile file = read_trajectory(opt.out);
    std::vector<const TrajectoryEpisode*> episodes;
    for (const TrajectoryEpisode& ep : file.episodes) episodes.push_back(&ep);
    int pictures = 0;
    const std::string gif = encode_gif(episodes, GifOptions{}, &pictures);
    write_atomically(opt.gif, gif);
    std::printf("  wrote %s (%d pictures, %.1f KB)\n", opt.gif.c_str(), pictures, gif.size() / 1024.0);
  }
  return 0;
}

}  // namespace

void add_play_command(CLI::App& app, std::vector<Command>& commands) {
  auto opt = std::make_shared<PlayOptions>();
  CLI::App* cmd =
      app.add_subcommand("play", "Record episodes into a trajectory file (view with `hns replay`)");
  cmd->add_option("--scene", opt->scene, "Scene (the list below; default quadrant, or the checkpoint's)")
      ->check(CLI::IsMember(batch::scene_names()));
  cmd->footer(scene_help());
  CLI::Option* random = cmd->add_flag("--random", opt->random, "Uniformly random actions (the default)");
  cmd->add_option("--checkpoint", opt->checkpoint,
                  "Act with the policy of a training checkpoint or exported policy (its scene)")
      ->excludes(random);
  cmd->add_option("--episodes", opt->episodes, "Whole episodes to record")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd->add_option("--seed", opt->seed_text, "Seed of scenes and actions, 0 .. 2^64 - 1")
      ->capture_default_str();
  cmd->add_option("--envs", opt->envs, "Envs played side by side")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  cmd->add_option("--threads", opt->threads, "Worker threads (0 = all the machine has)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  cmd->add_option("--hiders", opt->hiders, "Fix the hider count")->check(CLI::Range(0, 32));
  cmd->add_option("--seekers", opt->seekers, "Fix the seeker count")->check(CLI::Range(0, 32));
  cmd->add_option("--boxes", opt->boxes, "Fix the box count")->check(CLI::Range(0, 32));
  cmd->add_option("--ramps", opt->ramps, "Fix the ramp count")->check(CLI::Range(0, 16));
  cmd->add_option("--out", opt->out, "Trajectory file to write")->required();
  cmd->add_option("--gif", opt->gif,
                  "Also write an animated GIF of the episodes (320 px; hns replay --gif has the options)");
  cmd->add_option("--html", opt->html, "Also write the recording's replay page (as hns replay --html)");
  commands.push_back({cmd, [opt] {
                        opt->seed = parse_seed("--seed", opt->seed_text);
                        return run_play(*opt);
                      }});
}

}  // namespace hns::tools
