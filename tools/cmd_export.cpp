// `hns export`: a run's checkpoint as an exported policy (ppo::Trainer::export_policy; docs/training.md
// "Exported policies"): the networks and normalisers without the optimiser, for models/ and for sharing.
//
//   hns export CHECKPOINT|RUN --out FILE
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "cli.hpp"
#include "ppo/trainer.hpp"

namespace hns::tools {
namespace {

struct ExportOptions {
  std::string checkpoint;  // a checkpoint file, or a run folder (its checkpoint.bin)
  std::string out;
};

int run_export(const ExportOptions& opt) {
  std::error_code ec;
  const std::string checkpoint = std::filesystem::is_directory(opt.checkpoint, ec)
                                     ? (std::filesystem::path(opt.checkpoint) / "checkpoint.bin").string()
                                     : opt.checkpoint;
  check_output_path("--out", opt.out, {checkpoint});
  uint64_t bytes = 0;
  ppo::TrainConfig cfg;
  try {
    cfg = ppo::Trainer::checkpoint_config(checkpoint);
    bytes = ppo::Trainer::export_policy(checkpoint, opt.out);
  } catch (const std::runtime_error& e) {
    std::fprintf(stderr, "hns export: %s\n", e.what());
    return 2;
  }
  std::printf("hns export: wrote %s (%.1f KB): the %s model of a %s run, precision %s\n", opt.out.c_str(),
              double(bytes) / 1024.0, cfg.model.c_str(), cfg.scene.c_str(), cfg.precision.c_str());
  std::printf("  watch it: hns play --checkpoint %s --episodes 2 --out play.traj --html play.html\n",
              opt.out.c_str());
  return 0;
}

}  // namespace

void add_export_command(CLI::App& app, std::vector<Command>& commands) {
  auto opt = std::make_shared<ExportOptions>();
  CLI::App* cmd = app.add_subcommand(
      "export", "Write a run's policy without its optimiser state (for hns play, --init-from, Policy.load)");
  cmd->add_option("checkpoint", opt->checkpoint, "A run's checkpoint.bin, or its run folder")->required();
  cmd->add_option("--out", opt->out, "Exported policy to write")->required();
  commands.push_back({cmd, [opt] { return run_export(*opt); }});
}

}  // namespace hns::tools
