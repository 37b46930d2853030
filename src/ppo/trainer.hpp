// The synchronous PPO self-play loop (paper appendix B, docs/game.md §10.4): every agent of every env acts
// from one shared policy; one iteration is
//
//   rollout   T = horizon x episodes_per_iteration steps of all envs: obs -> ActorCritic::act (sampled
//             actions, log-probs, normalised values, LSTM states carried, zeroed at episode starts) ->
//             BatchSim::step; the LSTM states entering every BPTT chunk are kept
//   targets   windowed GAE and TD(λ) returns per agent row, value-target normaliser update, advantages
//             z-scored over the buffer
//   update    epochs x minibatches of shuffled BPTT chunks, stratified by blocks of envs (each block's share
//             of a minibatch one gradient group): clipped surrogate + value loss - entropy bonus,
//             global-norm clip, Adam
//   stats     observation normaliser update (after the update, so rollout and update see the same one)
//
// Buffer layout (structure of arrays, step-major): row = t * G + g for step t < T and agent row
// g = env * max_agents + agent < G. Padding agent slots are stepped through the network but carry mask 0 and
// take no part in any loss or statistic. Observations are normalised once, while copied from the simulator
// (the observation normaliser moves only between iterations), and read by both networks in the rollout and
// in the update. A minibatch is a sequence-major list of rollout rows (row = chunk * bptt + j) that
// ActorCritic::forward_backward reads the observations through; its targets and states are gathered.
//
// Determinism: the simulator and the networks are bit-identical for any thread count; everything here is
// serial or over fixed partitions, and the random numbers (action sampling, chunk shuffles) are
// counter-derived from (seed, iteration, step), so nothing but the iteration needs saving to resume.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "batch/batch_sim.hpp"
#include "nn/actor_critic.hpp"
#include "nn/adam.hpp"
#include "nn/obs_normalizer.hpp"
#include "ppo/comm.hpp"
#include "ppo/intrinsic_reward.hpp"
#include "ppo/train_config.hpp"

namespace hns::ppo {

// Running mean and std of the value targets (docs/game.md §10.2): debiased EMA of the mean and of the square,
// one update per iteration, std = sqrt(max(E[x²] - mean², 1e-2)).
struct ScalarNormalizer {
  double beta = 0.99999;
  double biased_mean = 0, biased_sq = 0, debias = 0;
  void update(double batch_mean, double batch_sq);
  double mean() const { return debias > 0 ? biased_mean / debias : 0.0; }
  double std() const;
};

// What one iteration measured.
struct IterationMetrics {
  int64_t iteration = 0;  // 1-based count of iterations done
  // The networks' precision (fp32 | bf16) in a run's first iteration (the first row of metrics.jsonl);
  // empty, and not written, in the others.
  std::string precision;
  int64_t agent_steps = 0;  // cumulative over the run, real agents only
  int64_t env_steps = 0;    // cumulative
  double seconds = 0;       // wall time of this iteration
  double steps_per_s = 0;   // agent-steps per second of this iteration
  // Episodes that ended during the iteration (means over them).
  int episodes = 0;
  double hider_reward = 0, seeker_reward = 0;  // episode returns: summed mean reward per team
  double intrinsic_reward = 0;  // episode return of the intrinsic reward (config intrinsic; 0 without)
  // The per-episode statistics of batch::EpisodeStats (docs/game.md §7 and the stage detectors), same names.
#define HNS_DECLARE_EPISODE_MEAN(name, doc) double name = 0;
  HNS_EPISODE_STATS(HNS_DECLARE_EPISODE_MEAN)
#undef HNS_DECLARE_EPISODE_MEAN
  // Update diagnostics (means over minibatches).
  double policy_loss = 0, value_loss = 0, entropy = 0, approx_kl = 0, clip_frac = 0;
  double explained_variance = 0, grad_norm = 0;
  double value_mean = 0, value_std = 0;  // value-target normaliser after the update
  // Wall seconds per phase: simulate (BatchSim::step), observe (observations normalised into the buffer,
  // masks widened, the normaliser's sums and update), infer (ActorCritic::act), learn (targets, gathers,
  // forward/backward, Adam); learn = t_targets (GAE, value normaliser, minibatch gathers: outside the
  // networks) + t_backward (forward + loss + backward of the minibatches) + t_optimizer (Adam).
  double t_simulate = 0, t_observe = 0, t_infer = 0, t_learn = 0, t_other = 0;
  double t_targets = 0, t_backward = 0, t_optimizer = 0;
  double t_intrinsic = 0;       // of learn: RND's forward passes and predictor steps (intrinsic = rnd)
  double t_comm = 0;            // of all the above, exchanging with and waiting for the other ranks
  int64_t unstable_resets = 0;  // envs reset by numerical trouble during this iteration

  std::string to_json() const;  // one line, no newline
};

// Raised when a loss or gradient turns non-finite: the run must stop and keep its last good checkpoint. The
// poisoned minibatch is not applied, but earlier minibatches of the iteration already moved the parameters,
// the Adam moments and the value normaliser: discard the Trainer (or load() the checkpoint) afterwards.
struct NumericalError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class Trainer {
 public:
  // Validates the config (physics::ConfigError) and builds simulator, networks and optimiser; parameters are
  // initialised from the seed. `comm`: the processes (ranks) training this run together, each constructing
  // its Trainer with the same config (null: this process alone). Rank r steps the envs of update blocks
  // [K r / R, K (r + 1) / R) (K = config.update_blocks(); more ranks than blocks is a ConfigError); results
  // (weights, optimiser, normalisers, metrics) are the same bits on every rank and for any rank count.
  explicit Trainer(const TrainConfig& config, Comm* comm = nullptr);
  ~Trainer();
  Trainer(const Trainer&) = delete;
  Trainer& operator=(const Trainer&) = delete;

  // One rollout + update. Throws NumericalError if a loss or gradient is not finite.
  IterationMetrics iterate();

  const TrainConfig& config() const { return cfg_; }
  int64_t iteration() const { return iteration_; }
  int64_t agent_steps() const { return agent_steps_; }
  const nn::ActorCritic& net() const { return *net_; }
  // This rank's envs: [first_env(), first_env() + sim().num_envs()) of the run's.
  const batch::BatchSim& sim() const { return *sim_; }
  int first_env() const { return env0_; }
  const Comm& comm() const { return *comm_; }

  // Checkpoint file (format in docs/training.md): magic, version, payload, FNV-1a 64 checksum. save() writes
  // a temporary file beside `path` and renames it over `path`. load() refuses (std::runtime_error with the
  // reason) a file that is truncated, corrupt, of another version or of a run with another identity.
  // kResume restores everything and requires every results-affecting key to match; kPolicy restores the
  // networks, optimiser and normalisers of a checkpoint of the same scene and model (for acting, not for
  // continuing the run).
  enum class LoadMode { kResume, kPolicy };
  void save(const std::string& path) const;
  void load(const std::string& path, LoadMode mode = LoadMode::kResume);
  // FNV-1a 64 of what save() would write (config, counters, weights, optimiser, normalisers): the ranks of a
  // run compare it before they start, so that none trains from another config or checkpoint.
  uint64_t fingerprint() const;
  // The config stored in a checkpoint (the file is checked as load() checks it).
  static TrainConfig checkpoint_config(const std::string& path);
  // Exported policy (docs/training.md "Exported policies"): a checkpoint's config, counters, both networks'
  // weights and the normalisers, without Adam's moments, the episode list or exploration state (about a third
  // of a checkpoint's size). It acts (load(kPolicy): hns play --checkpoint, Python's Policy.load) and starts
  // runs (initialize_from with init_optimizer = 0); load(kResume) refuses it. export_policy() writes one from
  // a checkpoint, atomically, and returns its size in bytes; it refuses (std::runtime_error) a damaged
  // checkpoint or one that is already an export.
  static uint64_t export_policy(const std::string& checkpoint, const std::string& out);
  // Starts this (new) run from a checkpoint of the same model whose scene has the same entity types
  // (config keys init_*): the policy's weights always; the value net's with init_value; the observation
  // normaliser (and, with the value net, the return normaliser) with init_normalizers; Adam's moments and
  // step count with init_optimizer; each network's head (final layer norm, output layer) unless init_heads
  // is 0. Everything else (iteration, counters, episodes) starts fresh. Refuses
  // (std::runtime_error with the reason) a damaged file or another network, leaving the trainer untouched.
  // Returns what it carried, for the progress line.
  std::string initialize_from(const std::string& path);
  const nn::ObsNormalizer& obs_normalizer() const { return *obs_norm_; }
  const nn::Adam& optimizer() const { return *adam_; }
  const ScalarNormalizer& value_normalizer() const { return value_norm_; }

  // While on, iterations record their phases (rollout: observe, infer, simulate per step, with the batch's
  // per-env phases; learn: targets, gather, forward+backward and optimizer per minibatch) as trace events;
  // the trainer's own are on thread -1. Times in ns since sim().trace_epoch().
  void set_tracing(bool on);
  std::vector<batch::TraceEvent> take_trace();

 private:
  struct Buffers;
  struct CheckpointState;
  // Reads and checks a whole checkpoint; `mismatch` may refuse it by its config (a non-empty reason) before
  // its arrays are read. `to_resume` refuses an exported policy first (it cannot continue a run).
  CheckpointState read_checkpoint(const std::string& path,
                                  const std::function<std::string(const TrainConfig&)>& mismatch,
                                  bool to_resume = false) const;
  // Refuses (std::runtime_error) values no run can produce: non-finite weights, moments or normalisers,
  // negative counts or second moments.
  static void check_values(const CheckpointState& st, const std::string& path);
  std::string checkpoint_payload() const;
  void rollout(IterationMetrics& m);
  // The rollout's steps at step t: the observations into the buffer (normalised) and the normaliser sums,
  // the masks, reset flags, entering LSTM states and uniforms (returns the real agents counted); the
  // networks' actions and values; the rewards, episode ends and finished episodes' statistics. Then, after
  // the last step, the episodes the next rollout starts and the iteration's episode statistics.
  int64_t observe_step(int t);
  void infer_step(int t);
  void record_step(int t);
  void finish_rollout(IterationMetrics& m, int64_t simulated);
  void compute_targets(IterationMetrics& m);
  void update(IterationMetrics& m);
  // The update's steps: this rank's valid chunks per block (returns their count); the minibatch buffers
  // sized for the largest minibatch; minibatch mb's chunks gathered (returns its real agent-steps here); one
  // minibatch's forward, backward, gradient sum and Adam step, its statistics added to `sums`.
  struct UpdateSums;
  int64_t collect_chunks();
  void size_minibatch(int minibatches);
  int64_t gather_minibatch(int mb, int minibatches);
  void train_minibatch(IterationMetrics& m, UpdateSums& sums, int epoch, int mb, int64_t total,
                       std::chrono::steady_clock::time_point tp);
  void restart_envs();
  // First env of update block k (k = blocks_: the end).
  int block_env(int k) const;
  // The rollout's observation sums of every block, merged in block order across ranks, applied.
  void apply_obs_sums();
  // Records [begin, now) as a trainer phase when tracing; returns now.
  std::chrono::steady_clock::time_point mark(const char* phase, std::chrono::steady_clock::time_point begin);

  TrainConfig cfg_;
  std::unique_ptr<Comm> own_comm_;  // when the constructor was given none
  Comm* comm_ = nullptr;
  int blocks_ = 0;               // K update blocks of the run
  int block0_ = 0, block1_ = 0;  // this rank's blocks [block0_, block1_)
  int env0_ = 0, env1_ = 0;      // their envs [env0_, env1_)
  int rollout_steps_ = 0;        // T
  int rows_ = 0;                 // G = this rank's envs x max agents
  std::unique_ptr<batch::BatchSim> sim_;
  std::unique_ptr<nn::ActorCritic> net_;
  std::unique_ptr<nn::Adam> adam_;
  std::unique_ptr<nn::ObsNormalizer> obs_norm_;
  ScalarNormalizer value_norm_;
  std::unique_ptr<Buffers> buf_;
  // The exploration bonus (config intrinsic), and each local env's intrinsic return so far this episode.
  std::unique_ptr<IntrinsicReward> intrinsic_;
  std::vector<double> intrinsic_return_;
  int64_t iteration_ = 0;
  int64_t agent_steps_ = 0;
  int64_t env_steps_ = 0;
  std::vector<int32_t>
      next_episode_;          // per env of the run (every rank holds all): the next iteration's episode
  bool need_restart_ = true;  // envs must be (re)started before the next rollout
  bool tracing_ = false;
  std::vector<batch::TraceEvent> trace_;
};

}  // namespace hns::ppo
