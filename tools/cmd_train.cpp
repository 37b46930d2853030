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
#include "train_folder.hpp"
#ifdef HNS_HAVE_MPI
#include "ppo/mpi_comm.hpp"
#endif
#include "batch/scenes.hpp"
#include "nn/bf16_gemm.hpp"
#include "nn/kernels.hpp"
#include "nn/precision.hpp"
#include "physics/scene.hpp"
#include "ppo/arithmetic.hpp"
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

// Records `episodes` episodes with the trainer's current policy into `path` (atomically), for the report.
void record_replay(const ppo::Trainer& trainer, const std::string& path, int episodes) {
  const ppo::TrainConfig& cfg = trainer.config();
  ppo::Policy policy(trainer, cfg.seed + uint64_t(trainer.iteration()));
  RecordConfig rc;
  rc.scene = cfg.scene;
  rc.episodes = episodes;
  rc.game = cfg.batch_config();
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

// Ctrl-C, SIGTERM and SIGUSR1 ask for a graceful stop (g_stop) until restore_stop_signals(). SIGUSR1 too:
// mpirun forwards it to every rank (it ends a job's ranks a second after Ctrl-C or SIGTERM, often before the
// checkpoint), so `kill -USR1 <mpirun>` is the graceful stop of a run over MPI.
void catch_stop_signals() {
  g_stop.store(false);
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);
  std::signal(SIGUSR1, on_interrupt);
}

void restore_stop_signals() {
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  std::signal(SIGUSR1, SIG_DFL);
}

// The iterations of a rank other than 0: the same loop and stop decisions, no output.
int follow(ppo::Trainer& trainer, const ppo::TrainConfig& cfg, ppo::Comm& comm) {
  catch_stop_signals();
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
  restore_stop_signals();
  return status;
}

// What the options make of a run, before its trainer exists: the config, the run folder and its files.
struct RunSetup {
  ppo::TrainConfig cfg;
  ppo::FolderLock lock;  // rank 0 holds the run folder while it runs
  std::string dir;
  bool resume = false;
  std::string run_precision;  // resuming: the precision of the run's config.json
  std::string init_what;      // how the checkpoint to start from was named, for messages
  std::string ckpt, metrics_path, replay_path, config_path;

  void name_files() {
    ckpt = (fs::path(dir) / "checkpoint.bin").string();
    metrics_path = (fs::path(dir) / "metrics.jsonl").string();
    replay_path = (fs::path(dir) / "replay.traj").string();
    config_path = (fs::path(dir) / "config.json").string();
  }
};

// The config a run starts from: a resumed run's config.json (its folder locked by rank 0), or --config.
void read_run_config(const TrainOptions& opt, bool lead, RunSetup& run) {
  ppo::TrainConfig& cfg = run.cfg;
  run.dir = opt.out;
  run.resume = !opt.resume.empty();
  if (run.resume) {
    if (!opt.out.empty())
      throw physics::ConfigError("--out and --resume: give one (a resumed run stays in its folder)");
    if (!opt.config_file.empty())
      throw physics::ConfigError("--config and --resume: a resumed run keeps its config.json");
    run.dir = opt.resume;
    if (opt.overwrite)
      throw physics::ConfigError(
          "--overwrite and --resume: give one (--resume continues the run in its folder)");
    if (!fs::exists(fs::path(run.dir) / "checkpoint.bin")) {
      // A run starting in the folder holds its lock before its first checkpoint: name that process.
      if (lead && fs::exists(fs::path(run.dir) / ppo::FolderLock::kFileName))
        (void)lock_run_folder("--resume", run.dir);
      throw physics::ConfigError("--resume " + run.dir + ": no checkpoint.bin there");
    }
    if (lead) run.lock = lock_run_folder("--resume", run.dir);
    const std::string path = (fs::path(run.dir) / "config.json").string();
    cfg.merge_run_json(read_text(path, "--resume: run config"), path);
    run.run_precision = cfg.precision;
  } else if (!opt.config_file.empty()) {
    cfg.merge_json(read_text(opt.config_file, "--config"), opt.config_file);
  }
}

// Flags win over files. A key given both by its own flag and by --set is refused: one of the two values
// would be dropped unchecked.
void apply_flags(const TrainOptions& opt, RunSetup& run) {
  ppo::TrainConfig& cfg = run.cfg;
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
    if (run.resume)
      throw physics::ConfigError("--init-from and --resume: a resumed run continues from its own checkpoint");
    cfg.init_from = *opt.init_from;
  }
}

// The checkpoint a new run starts from: named by --init-from, or by init_from of --config or --set.
// Recorded as an absolute path, so the run's config.json names it from anywhere.
void check_init_from(const TrainOptions& opt, RunSetup& run) {
  ppo::TrainConfig& cfg = run.cfg;
  run.init_what = opt.init_from ? "--init-from " : "config key init_from = ";
  if (run.resume || cfg.init_from.empty()) return;
  std::error_code ec;
  if (fs::is_directory(cfg.init_from, ec))
    throw physics::ConfigError(run.init_what + cfg.init_from + ": is a folder, not a checkpoint file");
  if (!fs::exists(cfg.init_from, ec))
    throw physics::ConfigError(run.init_what + cfg.init_from + ": no such checkpoint file");
  if (!fs::is_regular_file(cfg.init_from, ec)) {
    struct stat st {};
    const std::string kind =
        ::stat(cfg.init_from.c_str(), &st) == 0 ? ppo::special_file_kind(st.st_mode) : "not a regular file";
    throw physics::ConfigError(run.init_what + cfg.init_from + " is " + kind + ", not a checkpoint file");
  }
  cfg.init_from = fs::absolute(cfg.init_from).lexically_normal().string();
}

// The precision that runs on this machine: auto is resolved here, so config.json (and the checkpoint) name
// fp32 or bf16, and a resumed run keeps its precision. bf16 on a CPU without it is refused, not emulated.
void resolve_precision(RunSetup& run) {
  ppo::TrainConfig& cfg = run.cfg;
  try {
    cfg.precision = std::string(nn::precision_name(cfg.resolve_precision()));
  } catch (const physics::ConfigError&) {
    if (!run.resume || cfg.precision != run.run_precision || nn::CpuFeatures::detect().avx512_bf16) throw;
    throw physics::ConfigError(
        "--resume " + run.dir + ": the run trains in precision " + cfg.precision +
        " (its config.json), and this CPU has no AVX512-BF16 (bf16 is not emulated): resume it on a CPU that "
        "has it (AMD Zen 4 or later, Intel Cooper Lake, Sapphire Rapids or later); a run keeps its "
        "precision");
  }
}

// Every rank checks its machine for the ranks there (each counted with the largest share).
void check_run_memory(const ppo::TrainConfig& cfg, ppo::Comm& comm) {
  check_memory("envs = " + std::to_string(cfg.envs) +
                   (comm.size() > 1 ? " (" + std::to_string(cfg.envs_per_rank(comm.size())) +
                                          " on this rank of " + std::to_string(comm.size()) + ")"
                                    : std::string()) +
                   " with the " + cfg.model + " model and " + std::to_string(cfg.grad_groups) +
                   " gradient groups",
               cfg.estimated_bytes(comm.size()) * size_t(comm.ranks_on_this_machine()));
}

// The trainer's start: the checkpoint it resumes or starts from, loaded before the folder is created or any
// file of it removed (a refused checkpoint changes nothing). Returns 0, or the exit status of a refusal;
// `initialized` says what a start from another run's checkpoint carried.
int load_start(ppo::Trainer& trainer, const RunSetup& run, bool lead, std::string& initialized) {
  const ppo::TrainConfig& cfg = run.cfg;
  if (run.resume) {
    try {
      trainer.load(run.ckpt);
    } catch (const std::runtime_error& e) {
      std::fprintf(stderr, "hns train: cannot resume: %s\n", e.what());
      return 2;
    }
  } else if (!cfg.init_from.empty()) {
    std::error_code ec;
    if (lead && fs::equivalent(cfg.init_from, run.ckpt, ec)) {
      throw physics::ConfigError(run.init_what + cfg.init_from + " is the checkpoint of --out " + run.dir +
                                 ", which this run replaces: copy it elsewhere first");
    }
    try {
      initialized = trainer.initialize_from(cfg.init_from);
    } catch (const std::runtime_error& e) {
      std::fprintf(stderr, "hns train: %s%s: %s\n", run.init_what.c_str(), cfg.init_from.c_str(), e.what());
      return 2;
    }
  }
  return 0;
}

// A bf16 run resumed where another kernel runs its products (AMX tiles or vdpbf16ps, which round
// differently) than the one it started on (metrics.jsonl's first row names it) continues in the new
// kernel's arithmetic: said on stderr, since nothing else in the run folder records it. (Only the first
// kernel is recorded, so a later leg back on it says nothing.)
void warn_kernel_change(const std::string& earlier_metrics, const ppo::TrainConfig& cfg) {
  if (cfg.precision != "bf16") return;
  const std::string first = earlier_metrics.substr(0, earlier_metrics.find('\n'));
  if (first.empty()) return;
  const nlohmann::json row = nlohmann::json::parse(first, nullptr, false);
  if (!row.is_object() || !row.contains("bf16_kernel") || !row["bf16_kernel"].is_string()) return;
  const std::string started = row["bf16_kernel"].get<std::string>();
  const std::string now = nn::bf16::kernel_name(nn::bf16::kernel());
  if (started == now) return;
  std::fprintf(stderr,
               "hns train: warning: this bf16 run started on the %s kernel (metrics.jsonl's first row) and "
               "this leg runs on %s, which rounds differently: the run is not the one it would have been on "
               "%s alone%s\n",
               started.c_str(), now.c_str(), started.c_str(),
               started == "avx512-bf16" ? " (HNS_BF16_KERNEL=avx512-bf16 keeps the first kernel)" : "");
}

// Every rank must start from the same state: the same config and, resuming or starting from a checkpoint,
// the same file (a stale copy on one machine would train other weights there).
void check_same_start(const ppo::Trainer& trainer, ppo::Comm& comm) {
  if (comm.size() <= 1) return;
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

// A new run's folder: created, locked and marked as a run folder.
void create_run_folder(const TrainOptions& opt, RunSetup& run) {
  const std::string& dir = run.dir;
  std::error_code ec;
  fs::create_directories(dir, ec);  // before the --profile check: a profile may go into the new run folder
  if (ec) throw physics::ConfigError("--out " + dir + " cannot be created: " + ec.message());
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw physics::ConfigError("--out " + dir + " is not writable");
  // A folder that did not exist at the first check is locked now: of two runs started into one new folder
  // at once, the second to get here is refused.
  if (!run.lock.held()) {
    run.lock = lock_run_folder("--out", dir);
    // What another run may have put there between the first checks and the lock.
    check_run_folder(dir);
    check_no_run_unless(opt.overwrite, dir, run.ckpt);
  }
  if (!opt.config_file.empty() && fs::equivalent(opt.config_file, run.config_path, ec)) {
    throw physics::ConfigError("--config " + opt.config_file + " is the run's own config.json in --out " +
                               dir + ", which the run rewrites: copy it elsewhere first");
  }
  write_atomically((fs::path(dir) / kRunMarker).string(), "a run folder of hns train\n");
}

// --profile against the run's files (its marker and lock included), the checkpoint it starts from and
// --config. Before a new run's folder is made (`early`), a profile that goes into that folder is compared
// with those files only (it is tried for writing once the folder exists); any other is checked whole, so that
// a refusal leaves nothing behind.
void check_profile(const TrainOptions& opt, const RunSetup& run, bool early) {
  const fs::path dir(run.dir);
  const std::vector<std::string> inputs{run.ckpt,
                                        run.metrics_path,
                                        run.replay_path,
                                        run.config_path,
                                        run.cfg.init_from,
                                        opt.config_file,
                                        (dir / kRunMarker).string(),
                                        (dir / ppo::FolderLock::kFileName).string()};
  std::error_code ec;
  const fs::path parent = fs::weakly_canonical(fs::path(opt.profile), ec).parent_path();
  if (early && !fs::exists(dir, ec) && parent == fs::weakly_canonical(dir, ec)) {
    check_output_name("--profile", opt.profile);
    check_not_an_input("--profile", opt.profile, inputs);
    return;
  }
  check_output_path("--profile", opt.profile, inputs);
}

// A new run's files of an earlier run in the folder, removed. Nothing is removed unless every run file it
// would remove or replace is a file (or a link) hns can replace: a folder or a FIFO in a run file's place is
// refused first, with nothing touched.
void remove_old_run_files(const RunSetup& run) {
  if (!fs::exists(run.ckpt) && fs::exists(run.metrics_path)) {
    std::printf(
        "hns train: %s holds no checkpoint (an earlier run stopped before writing one): starting over\n",
        run.dir.c_str());
  }
  for (const std::string& f : {run.ckpt, run.metrics_path, run.replay_path, run.config_path}) {
    for (const std::string& p : {f, f + ".tmp"}) {
      std::error_code sec;
      // (ckpt, metrics and replay are removed, a link included; config.json is written through
      // check_replaceable, which follows a link)
      const fs::file_status st = f == run.config_path ? fs::status(p, sec) : fs::symlink_status(p, sec);
      if (sec || !fs::exists(st) || fs::is_regular_file(st) || fs::is_symlink(st)) continue;
      struct stat raw {};
      const std::string kind =
          ::lstat(p.c_str(), &raw) == 0 ? ppo::special_file_kind(raw.st_mode) : "not a file";
      throw physics::ConfigError(p + " is " + kind +
                                 ", where the run keeps a file of its own: hns removes and "
                                 "replaces only files it wrote; move it away, or use another --out");
    }
  }
  for (const std::string& f : {run.ckpt, run.metrics_path, run.replay_path}) {
    fs::remove(f);
    fs::remove(f + ".tmp");
  }
}

// The run's description at its start: sizes, memory, instruction set, precision, ranks, where it starts
// from and where its outputs go.
void print_run_start(const ppo::Trainer& trainer, const RunSetup& run, const ppo::Comm& comm,
                     const std::string& initialized) {
  const ppo::TrainConfig& cfg = run.cfg;
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
  if (run.resume)
    std::printf("  resuming %s at iteration %lld\n", run.dir.c_str(),
                static_cast<long long>(trainer.iteration()));
  if (!initialized.empty())
    std::printf("  starting from %s: %s\n", cfg.init_from.c_str(), initialized.c_str());
  std::printf(
      "  outputs in %s: metrics.jsonl, checkpoint.bin, config.json, replay.traj (see: hns report %s --html "
      "%s/report.html)\n",
      run.dir.c_str(), run.dir.c_str(), run.dir.c_str());
  std::fflush(stdout);
}

// --profile: the first iterations of this process are traced, then written.
class Profile {
 public:
  Profile(ppo::Trainer& trainer, const std::string& path)
      : trainer_(trainer), path_(path), until_(trainer.iteration() + kIterations) {
    if (!path_.empty()) trainer_.set_tracing(true);
  }
  // After each iteration: the trace is written once the profiled iterations are done.
  void after_iteration() {
    if (trainer_.iteration() == until_) finish();
  }
  void finish() {
    if (path_.empty()) return;
    trainer_.set_tracing(false);
    const std::vector<batch::TraceEvent> events = trainer_.take_trace();
    if (events.empty()) return;
    // A profile that cannot be written costs the profile, never the run.
    try {
      write_chrome_trace(path_, events);
      std::printf("  wrote %s (%zu events; open it in chrome://tracing or ui.perfetto.dev)\n", path_.c_str(),
                  events.size());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "hns train: warning: could not write the profile %s: %s (training goes on)\n",
                   path_.c_str(), e.what());
    }
  }

 private:
  static constexpr int kIterations = 3;
  ppo::Trainer& trainer_;
  const std::string& path_;
  const int64_t until_;
};

// The summed times of this process's iterations and the mean iteration time (for the ETA).
struct RunTimes {
  ppo::IterationMetrics totals;
  double mean_seconds = 0;
  int timed = 0;

  void add(const ppo::IterationMetrics& m) {
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
  }
};

// One iteration's progress line, and the stages it reached.
void print_progress(const ppo::IterationMetrics& m, const ppo::TrainConfig& cfg, const ppo::Comm& comm,
                    const RunTimes& times, const replay::StageTracker& stages,
                    const std::vector<int>& reached) {
  const double eta = times.mean_seconds * double(cfg.iterations - m.iteration);
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
}

// The iterations of rank 0: a metrics row and a progress line each, checkpoints (and the replay of the
// checkpoint's policy) every checkpoint_every iterations, at the end and on a graceful stop. Returns the exit
// status: 0, 3 (non-finite statistics) or 130 (stopped).
int train_loop(ppo::Trainer& trainer, const RunSetup& run, ppo::Comm& comm, std::string earlier_metrics,
               Profile& profile, RunTimes& times) {
  const ppo::TrainConfig& cfg = run.cfg;
  catch_stop_signals();
  // The paper's stages (docs/training.md "Stages"), announced as each first appears; a resumed run's earlier
  // iterations are read first, silently. A run without one of the teams has no stages to detect.
  replay::StageTracker stages(cfg.hiders == 0 || cfg.seekers == 0 ? "" : cfg.scene);
  {
    std::istringstream earlier(std::move(earlier_metrics));
    for (std::string line; std::getline(earlier, line);) stages.add(line);
    earlier_metrics = std::string();
  }
  std::ofstream metrics(run.metrics_path, std::ios::app);
  if (!metrics) throw std::runtime_error("cannot write " + run.metrics_path);
  int status = 0;
  int64_t last_checkpoint = trainer.iteration();  // of the checkpoint on disk (when there is one)
  while (trainer.iteration() < cfg.iterations) {
    ppo::IterationMetrics m;
    try {
      m = trainer.iterate();
    } catch (const ppo::NumericalError& e) {
      if (fs::exists(run.ckpt)) {
        std::fprintf(stderr,
                     "\nhns train: stopped: %s\n  the last good checkpoint is kept: %s (iteration %lld)\n",
                     e.what(), run.ckpt.c_str(), static_cast<long long>(last_checkpoint));
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
    if (!metrics) throw std::runtime_error("cannot write " + run.metrics_path);
    const std::vector<int> reached = stages.add(row);
    profile.after_iteration();
    times.add(m);
    print_progress(m, cfg, comm, times, stages, reached);
    const bool last = trainer.iteration() >= cfg.iterations;
    // Read once (a signal between two reads must not skip the checkpoint) and agreed by every rank.
    const bool stop = comm.any(g_stop.load());
    if (last || stop || trainer.iteration() % cfg.checkpoint_every == 0) {
      trainer.save(run.ckpt);
      last_checkpoint = trainer.iteration();
      // Episodes of the checkpoint's policy, for `hns report` (a discarded episode just leaves the old file).
      try {
        record_replay(trainer, run.replay_path, 2);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "hns train: warning: could not record %s: %s\n", run.replay_path.c_str(),
                     e.what());
      }
    }
    if (stop && !last) {
      std::printf(
          "hns train: interrupted after iteration %lld; checkpoint written. Continue with:\n"
          "  hns train --resume %s\n",
          static_cast<long long>(trainer.iteration()), run.dir.c_str());
      status = 130;
      break;
    }
  }
  restore_stop_signals();
  return status;
}

// Where this process's time went, as shares of its iterations' wall time.
void print_time_split(const ppo::IterationMetrics& totals, const ppo::Trainer& trainer,
                      const ppo::Comm& comm) {
  if (totals.seconds <= 0) return;
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
      (totals.t_observe + totals.t_targets + totals.t_other) * w, totals.t_observe * w, totals.t_targets * w,
      totals.t_other * w);
  if (totals.t_intrinsic > 0)
    std::printf("  RND's networks (forward passes and predictor steps), besides the above: %.1f%%\n",
                totals.t_intrinsic * w);
  if (comm.size() > 1)
    std::printf("  communication with and waiting for the other ranks (inside the phases above): %.1f%%\n",
                totals.t_comm * w);
}

// One process of a run (rank `comm.rank()` of `comm.size()`; a single process is rank 0 of 1). Every rank
// validates the same arguments and builds its Trainer; rank 0 alone touches the run folder, prints and
// writes.
int run_train(const TrainOptions& opt, ppo::Comm& comm) {
  const bool lead = comm.rank() == 0;
  RunSetup run;
  read_run_config(opt, lead, run);
  apply_flags(opt, run);
  check_init_from(opt, run);
  run.cfg.validate();
  resolve_precision(run);
  run.cfg.chunk_sequences = run.cfg.train_chunk();  // config.json names the chunk that runs (0: the model's)
  check_run_memory(run.cfg, comm);
  const ppo::TrainConfig& cfg = run.cfg;

  if (run.dir.empty()) run.dir = "runs/" + cfg.scene + "-" + cfg.model + "-seed" + std::to_string(cfg.seed);
  run.name_files();
  if (!run.resume && lead) {
    check_path_length("--out", run.dir);
    check_run_folder(run.dir);
    if (!opt.profile.empty()) check_profile(opt, run, true);
    std::error_code ec;
    if (fs::is_directory(run.dir, ec)) run.lock = lock_run_folder("--out", run.dir);
    check_no_run_unless(opt.overwrite, run.dir, run.ckpt);
  }
  // Ranks on different machines may resolve auto, or choose the bf16 kernel, differently.
  ppo::check_same_arithmetic(comm, ppo::arithmetic_description(cfg.resolve_precision()));
  ppo::Trainer trainer(cfg, &comm);
  std::string initialized;
  if (const int refused = load_start(trainer, run, lead, initialized)) return refused;
  check_same_start(trainer, comm);
  if (!lead) return follow(trainer, cfg, comm);
  if (!run.resume) create_run_folder(opt, run);
  if (!opt.profile.empty()) check_profile(opt, run, false);
  if (!run.resume) remove_old_run_files(run);

  std::string earlier_metrics;
  if (run.resume) {
    earlier_metrics = truncate_metrics(run.metrics_path, trainer.iteration());
    warn_kernel_change(earlier_metrics, cfg);
  }
  write_atomically(run.config_path, cfg.to_json());
  print_run_start(trainer, run, comm, initialized);

  Profile profile(trainer, opt.profile);
  RunTimes times;
  const int status = train_loop(trainer, run, comm, std::move(earlier_metrics), profile, times);
  if (status == 3) return status;
  profile.finish();  // a run shorter than the profiled iterations
  print_time_split(times.totals, trainer, comm);
  if (status == 0) {
    std::printf(
        "hns train: done, %lld iterations. Outputs in %s (metrics.jsonl, checkpoint.bin, config.json, "
        "replay.traj).\n  Report: hns report %s --html %s/report.html\n",
        static_cast<long long>(trainer.iteration()), run.dir.c_str(), run.dir.c_str(), run.dir.c_str());
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
  const std::string scenes = batch::scene_list(" | ");
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
