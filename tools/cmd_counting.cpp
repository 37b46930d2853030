// `hns counting`: the paper's object-counting probe (docs/transfer.md "Object counting"). For every condition
// (a frozen policy from the seed, the paper's baseline, and each --pretrained checkpoint's policy, frozen)
// and every seed: the policy watches --train-episodes + --test-episodes object-counting episodes, and a
// classification head on its final LSTM output learns to say how many of the 6 boxes went left. Results go
// to DIR/counting.json (every run) and DIR/counting.md (test accuracy, mean and 90 % interval over seeds).
//
//   hns counting --out DIR [--pretrained LABEL=CHECKPOINT ...] [--seeds N] [--model M] [--train-episodes N]
//                [--test-episodes N] [--epochs N] [--envs E] [--threads T]
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli.hpp"
#include "ppo/atomic_file.hpp"
#include "ppo/counting.hpp"
#include "ppo/eval.hpp"
#include "ppo/trainer.hpp"

namespace hns::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct CountingOptions {
  std::string out;
  bool overwrite = false;
  std::vector<std::string> pretrained;
  int seeds = 3;
  std::string model = "small";
  int train_episodes = 2048;
  int test_episodes = 1024;
  int epochs = 500;
  int envs = 64;
  int threads = 0;
};

struct Run {
  std::string condition;
  int seed = 0;
  ppo::CountingHeadResult result;
};

std::string table_markdown(const std::vector<Condition>& conditions, const std::vector<Run>& runs,
                           const CountingOptions& opt) {
  std::string md = "# Object counting\n\n";
  char buf[512];
  std::snprintf(
      buf, sizeof buf,
      "Test accuracy of a head (layer norm, dense 64 + ReLU, dense 7) on the frozen policy's final LSTM "
      "output, saying how many of 6 boxes went left; %d training and %d test episodes played by %d "
      "envs, %d epochs, model %s. Mean over seeds with the Student-t 90 %% interval.\n\n",
      opt.train_episodes, opt.test_episodes, opt.envs, opt.epochs, opt.model.c_str());
  md += buf;
  md += "| condition | test accuracy | train accuracy | majority class | seeds |\n|---|---|---|---|---|\n";
  for (const Condition& c : conditions) {
    std::vector<double> test, train, majority;
    for (const Run& r : runs) {
      if (r.condition != c.label) continue;
      test.push_back(r.result.test_accuracy);
      train.push_back(r.result.train_accuracy);
      majority.push_back(r.result.majority_accuracy);
    }
    if (test.empty()) continue;
    const ppo::MeanInterval t = ppo::mean_interval90(test), tr = ppo::mean_interval90(train),
                            mj = ppo::mean_interval90(majority);
    std::snprintf(buf, sizeof buf, "| %s | %.3f [%.3f, %.3f] | %.3f | %.3f | %d |\n", c.label.c_str(), t.mean,
                  t.lo, t.hi, tr.mean, mj.mean, t.n);
    md += buf;
  }
  return md;
}

int run_counting(const CountingOptions& opt) {
  if (opt.seeds < 1 || opt.seeds > 1000)
    throw physics::ConfigError("--seeds " + std::to_string(opt.seeds) + ": must be in [1, 1000]");
  if (opt.model != "small" && opt.model != "paper")
    throw physics::ConfigError("--model " + opt.model + ": must be small or paper");
  const std::vector<Condition> conditions = parse_conditions("random", opt.pretrained, opt.model);
  const fs::path dir(opt.out);
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw physics::ConfigError("--out " + opt.out + ": exists and is not a folder");
  check_path_length("--out", opt.out);
  // Earlier results are replaced only when asked.
  for (const char* name : {"counting.json", "counting.md"}) {
    if (fs::exists(fs::symlink_status(dir / name, ec)) && !opt.overwrite) {
      throw physics::ConfigError("--out " + opt.out + " holds " + name +
                                 " (an earlier probe): --overwrite replaces it, or give another folder");
    }
    try {
      ppo::check_replaceable((dir / name).string(), "--out:");
    } catch (const ppo::FileError& e) {
      throw physics::ConfigError(e.what());
    }
  }

  ppo::TrainConfig base;
  base.scene = "object-counting";
  base.model = opt.model;
  base.envs = 1;  // the trainer only holds the networks: the episodes run in the probe's own batch
  base.threads = opt.threads;
  base.init_heads = 1;
  base.init_value = 0;  // the value net plays no part
  base.init_normalizers = 1;
  base.validate();
  // Each checkpoint must carry into the counting scene (model, entity types): tried now, not after the
  // other conditions' runs.
  for (const Condition& c : conditions) {
    if (c.checkpoint.empty()) continue;
    ppo::TrainConfig cfg = base;
    cfg.init_from = c.checkpoint;
    ppo::Trainer probe(cfg);
    try {
      probe.initialize_from(c.checkpoint);
    } catch (const std::runtime_error& e) {
      throw physics::ConfigError("--pretrained " + c.label + "=" + c.checkpoint +
                                 " cannot act in object-counting: " + e.what());
    }
  }
  fs::create_directories(dir, ec);
  if (ec) throw physics::ConfigError("--out " + opt.out + ": cannot create the folder: " + ec.message());

  json settings = {{"model", opt.model},
                   {"train_episodes", opt.train_episodes},
                   {"test_episodes", opt.test_episodes},
                   {"epochs", opt.epochs},
                   {"envs", opt.envs},  // env e plays its own episodes: the scenes depend on the count
                   {"seeds", opt.seeds},
                   {"pretrained", json::object()}};
  for (const Condition& c : conditions)
    if (!c.checkpoint.empty())
      settings["pretrained"][c.label] = {{"path", c.checkpoint}, {"fnv1a64", c.fingerprint}};
  std::printf("hns counting: %s x %s, %d + %s each (model %s, %s)\n",
              count_text(static_cast<long long>(conditions.size()), "condition").c_str(),
              count_text(opt.seeds, "seed").c_str(), opt.train_episodes,
              count_text(opt.test_episodes, "episode").c_str(), opt.model.c_str(),
              threads_text(opt.threads).c_str());
  std::vector<Run> runs;
  for (const Condition& c : conditions) {
    for (int seed = 1; seed <= opt.seeds; ++seed) {
      ppo::TrainConfig cfg = base;
      cfg.seed = uint64_t(seed);
      cfg.init_from = c.checkpoint;
      ppo::Trainer trainer(cfg);
      if (!c.checkpoint.empty()) trainer.initialize_from(c.checkpoint);
      std::vector<float> train_x, test_x;
      std::vector<int32_t> train_y, test_y;
      ppo::collect_counting_states(trainer, 0, opt.train_episodes, opt.envs, opt.threads, train_x, train_y);
      ppo::collect_counting_states(trainer, opt.train_episodes, opt.test_episodes, opt.envs, opt.threads,
                                   test_x, test_y);
      ppo::CountingHeadConfig hc;
      hc.epochs = opt.epochs;
      hc.seed = uint64_t(seed);
      const int units = trainer.net().state_width() / 2;
      Run r{c.label, seed, ppo::train_counting_head(units, train_x, train_y, test_x, test_y, hc)};
      std::printf("  %s / seed %d: test accuracy %.3f (train %.3f, majority class %.3f)\n", c.label.c_str(),
                  seed, r.result.test_accuracy, r.result.train_accuracy, r.result.majority_accuracy);
      std::fflush(stdout);
      runs.push_back(r);
      json j = {{"kind", "hns-counting"}, {"settings", settings}, {"runs", json::array()}};
      for (const Run& x : runs) {
        j["runs"].push_back({{"condition", x.condition},
                             {"seed", x.seed},
                             {"test_accuracy", x.result.test_accuracy},
                             {"train_accuracy", x.result.train_accuracy},
                             {"majority_accuracy", x.result.majority_accuracy},
                             {"train_loss", x.result.train_loss}});
      }
      write_atomically((dir / "counting.json").string(), j.dump(1) + "\n");
      write_atomically((dir / "counting.md").string(), table_markdown(conditions, runs, opt));
    }
  }
  std::printf("\n%s\nhns counting: wrote %s and %s\n", table_markdown(conditions, runs, opt).c_str(),
              (dir / "counting.json").c_str(), (dir / "counting.md").c_str());
  return 0;
}

}  // namespace

void add_counting_command(CLI::App& app, std::vector<Command>& commands) {
  auto opt = std::make_shared<CountingOptions>();
  CLI::App* cmd = app.add_subcommand(
      "counting", "Object-counting probe: a head on frozen policies' memory, over seeds (docs/transfer.md)");
  cmd->add_option("--out", opt->out, "Folder for counting.json and counting.md")->required();
  cmd->add_option("--pretrained", opt->pretrained,
                  "LABEL=CHECKPOINT: a condition with that checkpoint's policy, frozen (repeatable)");
  cmd->add_option("--seeds", opt->seeds, "Seeds per condition (1 .. N)")->capture_default_str();
  cmd->add_option("--model", opt->model, "small | paper (a --pretrained checkpoint's model)")
      ->capture_default_str();
  cmd->add_option("--train-episodes", opt->train_episodes, "Episodes the head learns from")
      ->check(CLI::Range(7, 1 << 22))
      ->capture_default_str();
  cmd->add_option("--test-episodes", opt->test_episodes, "Held-out episodes it is scored on")
      ->check(CLI::Range(1, 1 << 22))
      ->capture_default_str();
  cmd->add_option("--epochs", opt->epochs, "Passes of the head's training")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd->add_option("--envs", opt->envs, "Envs playing episodes at once (the scenes depend on it)")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  cmd->add_option("--threads", opt->threads, "TBB threads (0 = all); results do not depend on it");
  cmd->add_flag("--overwrite", opt->overwrite,
                "Replace counting.json and counting.md of an earlier probe in --out");
  commands.push_back({cmd, [opt] { return run_counting(*opt); }});
}

}  // namespace hns::tools
