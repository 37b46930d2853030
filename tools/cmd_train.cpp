// `hns train`: synchronous PPO self-play (src/ppo/trainer.hpp), with a run folder holding config.json,
// metrics.jsonl and checkpoint.bin (docs/training.md).
//
//   hns train [--config FILE] [--scene S] [--model M] [--iterations K] [--seed S] [--threads T] [--envs N]
//             [--precision fp32|bf16|auto] [--set KEY=VALUE ...] [--out DIR | --resume DIR]
//             [--init-from CHECKPOINT] [--overwrite] [--profile FILE]
#include <sys/stat.h>
#include <unistd.h>
#include <atomic>
#include <csignal>
#include <cstdlib>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "batch/host.hpp"
#include "cli.hpp"
#ifdef HNS_HAVE_MPI
#include "ppo/mpi_comm.hpp"
#endif
#include "nn/kernels.hpp"
#include "nn/precision.hpp"
#include "physics/presets.hpp"
#include "physics/scene.hpp"
#include "ppo/atomic_file.hpp"
#include "ppo/policy.hpp"
#include "ppo/trainer.hpp"
#include "replay/metrics.hpp"
#include "replay/recorder.hpp"
#include "replay/stages.hpp"
#include "replay/trajectory.hpp"

namespace hns::tools {

using namespace hns::replay;  // trajectory files, recording, metrics rows
namespace {

namespace fs = std::filesystem;

struct TrainOptions {
  std::string config_file;
  std::optional<std::string> scene, model;
  std::optional<int> iterations, threads, envs;
  std::optional<std::string> seed;
  std::optional<std::string> precision;
  std::vector<std::string> sets;
  std::string out;
  std::string resume;
  std::optional<std::string> init_from;
  std::string profile;
  bool overwrite = false;
};

std::atomic<bool> g_stop{false};

extern "C" void on_interrupt(int) {
  g_stop.store(true);
  std::signal(SIGINT, SIG_DFL);  // a second Ctrl-C ends the process at once
  std::signal(SIGTERM, SIG_DFL);
  std::signal(SIGUSR1, SIG_DFL);
}

// A config file's text: a regular file of at most kMaxConfigBytes (a FIFO, a device, a huge file: exit 2).
std::string read_text(const std::string& path, const char* what) {
  try {
    return ppo::read_regular_file(path, ppo::kMaxConfigBytes, what);
  } catch (const std::exception& e) {
    throw physics::ConfigError(e.what());
  }
}

std::string duration_text(double s) {
  char buf[32];
  const long t = long(s + 0.5);
  if (t >= 3600) {
    std::snprintf(buf, sizeof buf, "%ldh%02ldm", t / 3600, (t / 60) % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%ldm%02lds", t / 60, t % 60);
  }
  return buf;
}

// Keeps the rows of metrics.jsonl up to `iteration` (a run stopped between writing a row and a checkpoint
// repeats those iterations on resume). Every whole row of an iteration the checkpoint covers is kept; a line
// that is not a complete JSON object with an integer "iteration" (torn by a crash, or damaged) is dropped
// and named on stderr, and the rows after it are kept. Returns the kept text.
std::string truncate_metrics(const std::string& path, int64_t iteration) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return "";
  std::string text;
  try {
    text = ppo::read_regular_file(path, ppo::kMaxMetricsBytes, "--resume:");
  } catch (const std::exception& e) {
    throw physics::ConfigError(e.what());
  }
  std::string kept;
  std::istringstream in(text);
  std::string line;
  std::vector<std::string> dropped;
  for (int64_t number = 1; std::getline(in, line); ++number) {
    // Only rows hns report reads (replay::is_iteration_record) are kept.
    if (!replay::is_iteration_record(line)) {
      if (!line.empty()) dropped.push_back(std::to_string(number));
      continue;
    }
    const nlohmann::json row = nlohmann::json::parse(line);
    if (row["iteration"].get<int64_t>() > iteration) continue;
    kept += line + "\n";
  }
  if (!dropped.empty()) {
    std::string lines;
    for (const std::string& n : dropped) lines += (lines.empty() ? "" : ", ") + n;
    std::fprintf(
        stderr,
        "hns train: warning: %s: line%s %s %s not a whole metrics row (torn by a crash or damaged) and "
        "%s dropped; every other row up to iteration %lld is kept\n",
        path.c_str(), dropped.size() > 1 ? "s" : "", lines.c_str(), dropped.size() > 1 ? "are" : "is",
        dropped.size() > 1 ? "were" : "was", static_cast<long long>(iteration));
  }
  write_atomically(path, kept);
  return kept;
}

// A run folder is marked by this file, which hns train writes into it; hns train only ever removes its own
// files (checkpoint.bin, metrics.jsonl, replay.traj) from a marked folder and leaves everything else alone.
constexpr const char* kRunMarker = ".hns-run";

// Whether `dir` may take a run: it does not exist, is empty, carries the marker, or holds a checkpoint.bin
// that loads as an hns checkpoint (a run of an hns from before the marker). Anything else is refused
// (ConfigError), so that no file of the user's is ever removed or overwritten, --overwrite included.
void check_run_folder(const std::string& dir) {
  std::error_code ec;
  if (!fs::exists(dir, ec)) return;
  if (!fs::is_directory(dir, ec)) throw physics::ConfigError("--out " + dir + " exists and is not a folder");
  if (fs::exists(fs::path(dir) / kRunMarker, ec)) return;
  fs::directory_iterator it(dir, ec);
  if (ec) throw physics::ConfigError("--out " + dir + " cannot be read: " + ec.message());
  // Empty, but for the lock file a refused start may have left (it marks nothing: any hns train creates it).
  while (it != fs::directory_iterator() && it->path().filename() == ppo::FolderLock::kFileName)
    it.increment(ec);
  if (it == fs::directory_iterator()) return;
  // A run from before the marker: a whole, valid checkpoint (its checksum checked), not 8 bytes of magic.
  const std::string ckpt = (fs::path(dir) / "checkpoint.bin").string();
  if (fs::is_regular_file(ckpt, ec)) {
    try {
      (void)ppo::Trainer::checkpoint_config(ckpt);
      return;
    } catch (const std::exception&) {
      // not a checkpoint of hns: the folder is not a run folder
    }
  }
  throw physics::ConfigError("--out " + dir + " holds '" + it->path().filename().string() +
                             "' and is not a run folder of hns train: give a new or empty folder (hns never "
                             "removes files it did not write, --overwrite included)");
}

// A folder holds a run only once a checkpoint is there (a run stopped before its first checkpoint, by a NaN
// or a crash in its first iterations, cannot be resumed, so the same command starts it over): refused
// unless `overwrite`.
void check_no_run_unless(bool overwrite, const std::string& dir, const std::string& ckpt) {
  std::error_code ec;
  if (fs::exists(ckpt, ec) && !overwrite) {
    throw physics::ConfigError("--out " + dir + " already holds a run: continue it with --resume " + dir +
                               ", or start over with --overwrite");
  }
}

// The run folder `dir`, locked for this process (ppo::FolderLock): a second hns train into a folder that a
// running one uses is refused at start (ConfigError, exit 2), naming the running one's process.
ppo::FolderLock lock_run_folder(const std::string& flag, const std::string& dir) {
  try {
    ppo::FolderLock lock(dir);
    if (!lock.warning().empty()) std::fprintf(stderr, "hns train: warning: %s\n", lock.warning().c_str());
    return lock;
  } catch (const std::runtime_error& e) {
    throw physics::ConfigError(flag + " " + e.what());
  }
}

// Records `episodes` episodes with the trainer's current policy into `path` (atomically), for the report.
void record_replay(const ppo::Trainer& trainer, const std::string& path, int episodes) {
  const ppo::TrainConfig& cfg = trainer.config();
  ppo::Policy policy(trainer, cfg.seed + uint64_t(trainer.iteration()));
  RecordConfig rc;
  rc.scene = cfg.scene;
  rc.episodes = episodes;
  rc.game.world = cfg.world();
  rc.game.num_envs = episodes;
  rc.game.threads = 1;
  rc.game.seed = cfg.seed * 1000003ULL + uint64_t(trainer.iteration());
  TrajectoryFile meta;
  meta.created_by = "hns train";
  meta.policy = "checkpoint.bin, iteration " + std::to_string(trainer.iteration());
  TrajectoryWriter writer(path, meta, episodes);
  record_episodes(
      rc, [&](const batch::BatchSim& sim, std::span<physics::AgentAction> a) { policy.act(sim, a); },
      [&](const TrajectoryEpisode& ep) { writer.add(ep); });
  writer.finish();
}

// The iterations of a rank other than 0: the same loop and stop decisions, no output.
int follow(ppo::Trainer& trainer, const ppo::TrainConfig& cfg, ppo::Comm& comm) {
  g_stop.store(false);
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);
  // SIGUSR1 too: mpirun forwards it to every rank (it ends a job's ranks a second after Ctrl-C or SIGTERM,
  // often before the checkpoint), so `kill -USR1 <mpirun>` is the graceful stop of a run over MPI.
  std::signal(SIGUSR1, on_interrupt);
  int status = 0;
  while (trainer.iteration() < cfg.iterations) {
    try {
      trainer.iterate();
    } catch (const ppo::NumericalError&) {
      return 3;  // every rank sees the same non-finite statistics; rank 0 reports
    }
    const bool stop = comm.any(g_stop.load());
    if (stop && trainer.iteration() < cfg.iterations) {
      status = 130;
      break;
    }
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  std::signal(SIGUSR1, SIG_DFL);
  return status;
}

// One process of a run (rank `comm.rank()` of `comm.size()`; a single process is rank 0 of 1). Every rank
// validates the same arguments and builds its Trainer; rank 0 alone touches the run folder, prints and
// writes.
int run_train(const TrainOptions& opt, ppo::Comm& comm) {
  const bool lead = comm.rank() == 0;
  ppo::FolderLock lock;  // rank 0 holds the run folder while it runs
  ppo::TrainConfig cfg;
  std::string dir = opt.out;
  const bool resume = !opt.resume.empty();
  std::string run_precision;  // resuming: the precision of the run's config.json
  if (resume) {
    if (!opt.out.empty())
      throw physics::ConfigError("--out and --resume: give one (a resumed run stays in its folder)");
    if (!opt.config_file.empty())
      throw physics::ConfigError("--config and --resume: a resumed run keeps its config.json");
    dir = opt.resume;
    if (opt.overwrite)
      throw physics::ConfigError(
          "--overwrite and --resume: give one (--resume continues the run in its folder)");
    if (!fs::exists(fs::path(dir) / "checkpoint.bin")) {
      // A run starting in the folder holds its lock before its first checkpoint: name that process.
      if (lead && fs::exists(fs::path(dir) / ppo::FolderLock::kFileName))
        (void)lock_run_folder("--resume", dir);
      throw physics::ConfigError("--resume " + dir + ": no checkpoint.bin there");
    }
    if (lead) lock = lock_run_folder("--resume", dir);
    const std::string path = (fs::path(dir) / "config.json").string();
    cfg.merge_run_json(read_text(path, "--resume: run config"), path);
    run_precision = cfg.precision;
  } else if (!opt.config_file.empty()) {
    cfg.merge_json(read_text(opt.config_file, "--config"), opt.config_file);
  }
  // Flags win over files. A key given both by its own flag and by --set is refused: one of the two values
  // would be dropped unchecked.
  const std::pair<const char*, bool> flag_keys[] = {{"scene", bool(opt.scene)},
                                                    {"model", bool(opt.model)},
                                                    {"iterations", bool(opt.iterations)},
                                                    {"threads", bool(opt.threads)},
                                                    {"envs", bool(opt.envs)},
                                                    {"seed", bool(opt.seed)},
                                                    {"precision", bool(opt.precision)},
                                                    {"init_from", bool(opt.init_from)}};
  for (const std::string& kv : opt.sets) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos) throw physics::ConfigError("--set " + kv + ": expected KEY=VALUE");
    const std::string key = kv.substr(0, eq);
    for (const auto& [name, given] : flag_keys) {
      if (given && key == name) {
        std::string flag = std::string("--") + name;
        if (flag == "--init_from") flag = "--init-from";
        throw physics::ConfigError("--set " + kv + " and " + flag + " both give " + key + ": give it once");
      }
    }
    cfg.set(key, kv.substr(eq + 1));
  }
  if (opt.scene) cfg.scene = *opt.scene;
  if (opt.model) cfg.model = *opt.model;
  if (opt.iterations) cfg.iterations = *opt.iterations;
  if (opt.threads) cfg.threads = *opt.threads;
  if (opt.envs) cfg.envs = *opt.envs;
  if (opt.seed) cfg.seed = parse_seed("--seed", *opt.seed);
  if (opt.precision) cfg.precision = *opt.precision;
  if (opt.init_from) {
    if (resume)
      throw physics::ConfigError("--init-from and --resume: a resumed run continues from its own checkpoint");
    cfg.init_from = *opt.init_from;
  }
  // The checkpoint a new run starts from: named by --init-from, or by init_from of --config or --set.
  // Recorded as an absolute path, so the run's config.json names it from anywhere.
  const std::string init_what = opt.init_from ? "--init-from " : "config key init_from = ";
  if (!resume && !cfg.init_from.empty()) {
    std::error_code ec;
    if (fs::is_directory(cfg.init_from, ec))
      throw physics::ConfigError(init_what + cfg.init_from + ": is a folder, not a checkpoint file");
    if (!fs::exists(cfg.init_from, ec))
      throw physics::ConfigError(init_what + cfg.init_from + ": no such checkpoint file");
    if (!fs::is_regular_file(cfg.init_from, ec)) {
      struct stat st {};
      const std::string kind =
          ::stat(cfg.init_from.c_str(), &st) == 0 ? ppo::special_file_kind(st.st_mode) : "not a regular file";
      throw physics::ConfigError(init_what + cfg.init_from + " is " + kind + ", not a checkpoint file");
    }
    cfg.init_from = fs::absolute(cfg.init_from).lexically_normal().string();
  }
  cfg.validate();
  // The precision that runs on this machine: auto is resolved here, so config.json (and the checkpoint) name
  // fp32 or bf16, and a resumed run keeps its precision. bf16 on a CPU without it is refused, not emulated.
  try {
    cfg.precision = std::string(nn::precision_name(cfg.resolve_precision()));
  } catch (const physics::ConfigError&) {
    if (!resume || cfg.precision != run_precision || nn::CpuFeatures::detect().avx512_bf16) throw;
    throw physics::ConfigError(
        "--resume " + dir + ": the run trains in precision " + cfg.precision +
        " (its config.json), and this CPU has no AVX512-BF16 (bf16 is not emulated): resume it on a CPU that "
        "has it (AMD Zen 4 or later, Intel Cooper Lake, Sapphire Rapids or later); a run keeps its "
        "precision");
  }
  // Every rank checks its machine for the ranks there (each counted with the largest share).
  check_memory("envs = " + std::to_string(cfg.envs) +
                   (comm.size() > 1 ? " (" + std::to_string(cfg.envs_per_rank(comm.size())) +
                                          " on this rank of " + std::to_string(comm.size()) + ")"
                                    : std::string()) +
                   " with the " + cfg.model + " model and " + std::to_string(cfg.grad_groups) +
                   " gradient groups",
               cfg.estimated_bytes(comm.size()) * size_t(comm.ranks_on_this_machine()));

  if (dir.empty()) dir = "runs/" + cfg.scene + "-" + cfg.model + "-seed" + std::to_string(cfg.seed);
  const std::string ckpt = (fs::path(dir) / "checkpoint.bin").string();
  const std::string metrics_path = (fs::path(dir) / "metrics.jsonl").string();
  const std::string replay_path = (fs::path(dir) / "replay.traj").string();
  if (!resume && lead) {
    check_path_length("--out", dir);
    check_run_folder(dir);
    std::error_code ec;
    if (fs::is_directory(dir, ec)) lock = lock_run_folder("--out", dir);
    check_no_run_unless(opt.overwrite, dir, ckpt);
  }
  // The trainer, and the checkpoint it resumes or starts from, before the folder is created or any file of it
  // removed: a refused checkpoint changes nothing.
  ppo::Trainer trainer(cfg, &comm);
  std::string initialized;
  if (resume) {
    try {
      trainer.load(ckpt);
    } catch (const std::runtime_error& e) {
      std::fprintf(stderr, "hns train: cannot resume: %s\n", e.what());
      return 2;
    }
  } else if (!cfg.init_from.empty()) {
    std::error_code ec;
    if (lead && fs::equivalent(cfg.init_from, ckpt, ec)) {
      throw physics::ConfigError(init_what + cfg.init_from + " is the checkpoint of --out " + dir +
                                 ", which this run replaces: copy it elsewhere first");
    }
    try {
      initialized = trainer.initialize_from(cfg.init_from);
    } catch (const std::runtime_error& e) {
      std::fprintf(stderr, "hns train: %s%s: %s\n", init_what.c_str(), cfg.init_from.c_str(), e.what());
      return 2;
    }
  }
  // Every rank must start from the same state: the same config and, resuming or starting from a checkpoint,
  // the same file (a stale copy on one machine would train other weights there).
  if (comm.size() > 1) {
    const uint64_t fp = trainer.fingerprint();
    const std::vector<double> mine = {double(fp >> 32), double(fp & 0xffffffffULL)};
    std::vector<double> all;
    comm.allgather(mine, all);
    for (int r = 1; r < comm.size(); ++r) {
      if (all[size_t(2 * r)] != all[0] || all[size_t(2 * r) + 1] != all[1]) {
        throw physics::ConfigError("rank " + std::to_string(r) +
                                   " starts from another config or checkpoint than rank 0 (every rank must "
                                   "see the same files and arguments: a shared run folder, the same build)");
      }
    }
  }
  if (!lead) return follow(trainer, cfg, comm);
  if (!resume) {
    std::error_code ec;
    fs::create_directories(dir, ec);  // before the --profile check: a profile may go into the new run folder
    if (ec) throw physics::ConfigError("--out " + dir + " cannot be created: " + ec.message());
    if (::access(dir.c_str(), W_OK | X_OK) != 0)
      throw physics::ConfigError("--out " + dir + " is not writable");
    // A folder that did not exist at the check above is locked now: of two runs started into one new
    // folder at once, the second to get here is refused.
    if (!lock.held()) {
      lock = lock_run_folder("--out", dir);
      // What another run may have put there between the checks above and the lock.
      check_run_folder(dir);
      check_no_run_unless(opt.overwrite, dir, ckpt);
    }
    if (!opt.config_file.empty() && fs::equivalent(opt.config_file, fs::path(dir) / "config.json", ec)) {
      throw physics::ConfigError("--config " + opt.config_file + " is the run's own config.json in --out " +
                                 dir + ", which the run rewrites: copy it elsewhere first");
    }
    write_atomically((fs::path(dir) / kRunMarker).string(), "a run folder of hns train\n");
  }
  if (!opt.profile.empty()) {
    check_output_path("--profile", opt.profile,
                      {ckpt, metrics_path, replay_path, (fs::path(dir) / "config.json").string(),
                       cfg.init_from, opt.config_file});
  }
  if (!resume) {
    if (!fs::exists(ckpt) && fs::exists(metrics_path)) {
      std::printf(
          "hns train: %s holds no checkpoint (an earlier run stopped before writing one): starting over\n",
          dir.c_str());
    }
    // Nothing is removed unless every run file it would remove or replace is a file (or a link) hns can
    // replace: a folder or a FIFO in a run file's place is refused first, with nothing touched.
    const std::string config_path = (fs::path(dir) / "config.json").string();
    for (const std::string& f : {ckpt, metrics_path, replay_path, config_path}) {
      for (const std::string& p : {f, f + ".tmp"}) {
        std::error_code sec;
        // (ckpt, metrics and replay are removed, a link included; config.json is written through
        // check_replaceable, which follows a link)
        const fs::file_status st = f == config_path ? fs::status(p, sec) : fs::symlink_status(p, sec);
        if (sec || !fs::exists(st) || fs::is_regular_file(st) || fs::is_symlink(st)) continue;
        struct stat raw {};
        const std::string kind =
            ::lstat(p.c_str(), &raw) == 0 ? ppo::special_file_kind(raw.st_mode) : "not a file";
        throw physics::ConfigError(p + " is " + kind +
                                   ", where the run keeps a file of its own: hns removes and "
                                   "replaces only files it wrote; move it away, or use another --out");
      }
    }
    for (const std::string& f : {ckpt, metrics_path, replay_path}) {
      fs::remove(f);
      fs::remove(f + ".tmp");
    }
  }

  std::string earlier_metrics;
  if (resume) earlier_metrics = truncate_metrics(metrics_path, trainer.iteration());
  write_atomically((fs::path(dir) / "config.json").string(), cfg.to_json());

  const batch::Layout& L = trainer.sim().layout();
  const std::string update = cfg.minibatch_chunks > 0
                                 ? "minibatches of at most " + count_text(cfg.minibatch_chunks, "chunk")
                                 : count_text(cfg.minibatches, "minibatch", "minibatches");
  std::printf(
      "hns train: scene %s, model %s (%zu parameters), %s x %s, %s per iteration, %s of %s, %s x %s, "
      "seed %llu, %s\n",
      cfg.scene.c_str(), cfg.model.c_str(), trainer.net().num_params(), count_text(cfg.envs, "env").c_str(),
      count_text(L.max_agents, "agent slot").c_str(), count_text(cfg.rollout_steps(), "step").c_str(),
      count_text(cfg.buffer_chunks(), "chunk").c_str(), count_text(cfg.bptt, "step").c_str(),
      count_text(cfg.epochs, "epoch").c_str(), update.c_str(), static_cast<unsigned long long>(cfg.seed),
      threads_text(cfg.threads).c_str());
  std::printf("  memory: about %.0f MiB estimated%s, %.0f MiB available\n",
              double(cfg.estimated_bytes(comm.size())) / (1 << 20), comm.size() > 1 ? " per rank" : "",
              double(batch::available_memory_bytes()) / (1 << 20));
  std::printf("  instruction set: %s\n", nn::kernels::isa_description().c_str());
  std::printf("  precision: %s\n", nn::precision_description(trainer.net().precision()).c_str());
  if (cfg.scene == "object-counting") {
    std::fprintf(stderr,
                 "hns train: warning: scene object-counting has no reward (it is the counting probe's scene: "
                 "hns counting, docs/transfer.md); this run trains on returns that are always 0\n");
  }
  if (comm.size() > 1) {
    std::printf("  %d ranks (MPI), %d update blocks; rank 0 steps envs [%d, %d)\n", comm.size(),
                cfg.update_blocks(), trainer.first_env(), trainer.first_env() + trainer.sim().num_envs());
  }
  if (resume)
    std::printf("  resuming %s at iteration %lld\n", dir.c_str(),
                static_cast<long long>(trainer.iteration()));
  if (!initialized.empty())
    std::printf("  starting from %s: %s\n", cfg.init_from.c_str(), initialized.c_str());
  std::printf(
      "  outputs in %s: metrics.jsonl, checkpoint.bin, config.json, replay.traj (see: hns report %s)\n",
      dir.c_str(), dir.c_str());
  std::fflush(stdout);

  // --profile: the first iterations of this process are traced, then written.
  constexpr int kProfileIterations = 3;
  const int64_t profile_until = trainer.iteration() + kProfileIterations;
  if (!opt.profile.empty()) trainer.set_tracing(true);
  auto finish_profile = [&] {
    if (opt.profile.empty()) return;
    trainer.set_tracing(false);
    const std::vector<batch::TraceEvent> events = trainer.take_trace();
    if (events.empty()) return;
    // A profile that cannot be written costs the profile, never the run.
    try {
      write_chrome_trace(opt.profile, events);
      std::printf("  wrote %s (%zu events; open it in chrome://tracing or ui.perfetto.dev)\n",
                  opt.profile.c_str(), events.size());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "hns train: warning: could not write the profile %s: %s (training goes on)\n",
                   opt.profile.c_str(), e.what());
    }
  };

  g_stop.store(false);
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);
  // SIGUSR1 too: mpirun forwards it to every rank (it ends a job's ranks a second after Ctrl-C or SIGTERM,
  // often before the checkpoint), so `kill -USR1 <mpirun>` is the graceful stop of a run over MPI.
  std::signal(SIGUSR1, on_interrupt);
  // The paper's stages (docs/training.md "Stages"), announced as each first appears; a resumed run's earlier
  // iterations are read first, silently. A run without one of the teams has no stages to detect.
  replay::StageTracker stages(cfg.hiders == 0 || cfg.seekers == 0 ? "" : cfg.scene);
  {
    std::istringstream earlier(std::move(earlier_metrics));
    for (std::string line; std::getline(earlier, line);) stages.add(line);
    earlier_metrics = std::string();
  }
  std::ofstream metrics(metrics_path, std::ios::app);
  if (!metrics) throw std::runtime_error("cannot write " + metrics_path);
  ppo::IterationMetrics totals;  // summed times of this process's iterations
  double mean_seconds = 0;
  int timed = 0;
  int status = 0;
  int64_t last_checkpoint = trainer.iteration();  // of the checkpoint on disk (when there is one)
  while (trainer.iteration() < cfg.iterations) {
    ppo::IterationMetrics m;
    try {
      m = trainer.iterate();
    } catch (const ppo::NumericalError& e) {
      if (fs::exists(ckpt)) {
        std::fprintf(stderr,
                     "\nhns train: stopped: %s\n  the last good checkpoint is kept: %s (iteration %lld)\n",
                     e.what(), ckpt.c_str(), static_cast<long long>(last_checkpoint));
      } else {
        std::fprintf(
            stderr,
            "\nhns train: stopped: %s\n  no checkpoint was written yet: run the same command to start "
            "over\n",
            e.what());
      }
      return 3;
    }
    const std::string row = m.to_json();
    metrics << row << "\n";
    metrics.flush();
    if (!metrics) throw std::runtime_error("cannot write " + metrics_path);
    const std::vector<int> reached = stages.add(row);
    if (trainer.iteration() == profile_until) finish_profile();
    for (auto [sum, v] : {std::pair{&totals.seconds, m.seconds},
                          {&totals.t_simulate, m.t_simulate},
                          {&totals.t_observe, m.t_observe},
                          {&totals.t_infer, m.t_infer},
                          {&totals.t_targets, m.t_targets},
                          {&totals.t_backward, m.t_backward},
                          {&totals.t_optimizer, m.t_optimizer},
                          {&totals.t_intrinsic, m.t_intrinsic},
                          {&totals.t_other, m.t_other},
                          {&totals.t_comm, m.t_comm}}) {
      *sum += v;
    }
    mean_seconds = (mean_seconds * timed + m.seconds) / (timed + 1);
    ++timed;
    const double eta = mean_seconds * double(cfg.iterations - m.iteration);
    const std::string ranks = comm.size() > 1 ? "  ranks " + std::to_string(comm.size()) : "";
    char intrinsic[48] = "";
    if (cfg.intrinsic != "none")
      std::snprintf(intrinsic, sizeof intrinsic, " intrinsic %+.2f", m.intrinsic_reward);
    std::printf(
        "iter %lld/%d  agent-steps %lld  %.0f steps/s  hider %+.2f seeker %+.2f%s  entropy %.3f  kl %.4f%s  "
        "ETA %s\n",
        static_cast<long long>(m.iteration), cfg.iterations, static_cast<long long>(m.agent_steps),
        m.steps_per_s, m.hider_reward, m.seeker_reward, intrinsic, m.entropy, m.approx_kl, ranks.c_str(),
        duration_text(eta).c_str());
    for (int k : reached) {
      std::printf("hns train: stage reached: %s\n", stages.stages()[size_t(k)].reached_text().c_str());
    }
    std::fflush(stdout);
    const bool last = trainer.iteration() >= cfg.iterations;
    // Read once (a signal between two reads must not skip the checkpoint) and agreed by every rank.
    const bool stop = comm.any(g_stop.load());
    if (last || stop || trainer.iteration() % cfg.checkpoint_every == 0) {
      trainer.save(ckpt);
      last_checkpoint = trainer.iteration();
      // Episodes of the checkpoint's policy, for `hns report` (a discarded episode just leaves the old file).
      try {
        record_replay(trainer, replay_path, 2);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "hns train: warning: could not record %s: %s\n", replay_path.c_str(), e.what());
      }
    }
    if (stop && !last) {
      std::printf(
          "hns train: interrupted after iteration %lld; checkpoint written. Continue with:\n"
          "  hns train --resume %s\n",
          static_cast<long long>(trainer.iteration()), dir.c_str());
      status = 130;
      break;
    }
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  std::signal(SIGUSR1, SIG_DFL);
  finish_profile();  // a run shorter than the profiled iterations
  if (totals.seconds > 0) {
    const double w = 100.0 / totals.seconds;
    const batch::PhaseTimes& ph = trainer.sim().phase_times();
    const double sim_thread = ph.total();
    const double v = sim_thread > 0 ? 100.0 / sim_thread : 0.0;
    std::printf(
        "time split: simulate %.1f%% (of its thread time: physics %.0f%%, mirror %.0f%%, "
        "vision+lidar %.0f%%, observations %.0f%%, rewards+resets %.0f%%), inference %.1f%%, "
        "forward+backward %.1f%%, "
        "optimizer %.1f%%, everything else %.1f%% (observations into the buffer %.1f%%, targets and row "
        "lists %.1f%%, "
        "other %.1f%%)\n",
        totals.t_simulate * w, ph.physics * v, ph.mirror * v, ph.perception * v, ph.observations * v,
        ph.rewards * v, totals.t_infer * w, totals.t_backward * w, totals.t_optimizer * w,
        (totals.t_observe + totals.t_targets + totals.t_other) * w, totals.t_observe * w,
        totals.t_targets * w, totals.t_other * w);
    if (totals.t_intrinsic > 0)
      std::printf("  RND's networks (forward passes and predictor steps), besides the above: %.1f%%\n",
                  totals.t_intrinsic * w);
    if (comm.size() > 1)
      std::printf("  communication with and waiting for the other ranks (inside the phases above): %.1f%%\n",
                  totals.t_comm * w);
  }
  if (status == 0) {
    std::printf(
        "hns train: done, %lld iterations. Outputs in %s (metrics.jsonl, checkpoint.bin, config.json, "
        "replay.traj).\n  Report: hns report %s --html %s/report.html\n",
        static_cast<long long>(trainer.iteration()), dir.c_str(), dir.c_str(), dir.c_str());
  }
  return status;
}

// hns train in this process alone, or as one rank of an MPI job (started by mpirun, mpiexec or srun).
int train_command(const TrainOptions& opt) {
#ifdef HNS_HAVE_MPI
  if (ppo::launched_by_mpi()) {
    ppo::MpiComm comm;
    const std::string who = comm.size() > 1 ? "hns train (rank " + std::to_string(comm.rank()) + ")" : "hns";
    int status = 0;
    try {
      status = run_train(opt, comm);
    } catch (const physics::ConfigError& e) {
      std::fprintf(stderr, "%s: bad configuration: %s\n", who.c_str(), e.what());
      status = 2;
    } catch (const std::bad_alloc&) {
      std::fprintf(stderr, "%s: error: out of memory (use fewer envs, a smaller model or more ranks)\n",
                   who.c_str());
      status = 1;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s: error: %s\n", who.c_str(), e.what());
      status = 1;
    }
    std::fflush(stdout);
    std::fflush(stderr);
    // A rank that fails ends them all (the others may be waiting for it); a run that finished, stopped on
    // request or stopped at a non-finite loss (every rank sees the same statistics) ends every rank normally.
    if (status != 0 && status != 130 && status != 3 && comm.size() > 1) comm.abort(status);
    return status;
  }
#else
  for (const char* var : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"}) {
    const char* n = std::getenv(var);
    if (n != nullptr && std::atoi(n) > 1) {
      throw physics::ConfigError(
          "this hns was built without MPI (HNS_MPI=OFF or no libopenmpi-dev), but it was started as one of " +
          std::string(n) +
          " processes: every one would train the whole run alone; build with MPI, or run "
          "hns train without mpirun");
    }
  }
#endif
  // srun without an MPI plugin starts plain processes, each of which would train the whole run alone.
  const char* tasks = std::getenv("SLURM_STEP_NUM_TASKS");
  if (tasks != nullptr && std::atoi(tasks) > 1) {
    throw physics::ConfigError("started by srun as " + std::string(tasks) +
                               " tasks without MPI (no PMI/PMIx): every one would train the whole run alone; "
                               "use srun --mpi=pmix with an MPI build, or one task");
  }
  ppo::SingleProcess single;
  return run_train(opt, single);
}

}  // namespace

void add_train_command(CLI::App& app, std::vector<Command>& commands) {
  auto opt = std::make_shared<TrainOptions>();
  CLI::App* sub = app.add_subcommand("train", "Train hide-and-seek agents with PPO self-play");
  sub->add_option("--config", opt->config_file, "Flat JSON config file (keys as in a run's config.json)");
  const ppo::TrainConfig defaults;
  const std::string scenes = physics::scene_list(" | ");
  auto dflt = [](const auto& value) {
    if constexpr (std::is_convertible_v<decltype(value), std::string>) {
      return " (default " + std::string(value) + ")";
    } else {
      return " (default " + std::to_string(value) + ")";
    }
  };
  sub->add_option("--scene", opt->scene, scenes + dflt(defaults.scene));
  sub->footer(scene_help());
  sub->add_option("--model", opt->model, "small | paper" + dflt(defaults.model));
  sub->add_option("--iterations", opt->iterations, "Total iterations of the run" + dflt(defaults.iterations));
  sub->add_option("--seed", opt->seed,
                  "Seed of worlds, initial weights and sampling, 0 .. 2^64 - 1" + dflt(defaults.seed));
  sub->add_option("--threads", opt->threads,
                  "TBB threads (0 = all); results do not depend on it" + dflt(defaults.threads));
  sub->add_option("--envs", opt->envs, "Game instances stepped together" + dflt(defaults.envs));
  sub->add_option("--precision", opt->precision,
                  "Matrix products: fp32 | bf16 (bf16 operands, float sums; needs AVX512-BF16) | auto (bf16 "
                  "where the CPU has it); config.json records the one that runs" +
                      dflt(defaults.precision));
  sub->add_option("--set", opt->sets, "Any config key, KEY=VALUE (repeatable), e.g. --set epochs=2");
  sub->add_option("--out", opt->out, "Run folder (default runs/SCENE-MODEL-seedS)");
  sub->add_option("--resume", opt->resume, "Continue the run in this folder from its checkpoint");
  sub->add_option("--init-from", opt->init_from,
                  "Start a new run from this checkpoint's weights (config keys init_*; docs/training.md)");
  sub->add_option("--profile", opt->profile,
                  "Write a per-phase Chrome trace (JSON) of the first 3 iterations to this file");
  sub->add_flag("--overwrite", opt->overwrite, "Start over in a --out folder that already holds a run");
  commands.push_back({sub, [opt] { return train_command(*opt); }});
}

}  // namespace hns::tools
