// Everything a training run is made of, validated, and its flat-JSON form (the `--config` file, the
// resolved `config.json` of a run folder and the identity stored in checkpoints).
//
// Rollouts are aligned to episodes: every iteration runs `episodes_per_iteration` whole episodes in every
// env, so an iteration starts with fresh episodes and zero LSTM states (what makes resume bit-identical
// without saving the physics state). GAE windows are therefore whole rollouts (docs/game.md §14 note in
// docs/training.md).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "batch/batch_sim.hpp"
#include "nn/precision.hpp"
#include "physics/world.hpp"

namespace hns::ppo {

// Most agent-step rows (steps x envs x agent slots) one rollout buffer may hold (validate() refuses more).
inline constexpr int64_t kMaxRolloutRows = int64_t(1) << 24;

struct TrainConfig {
  // Game and model.
  std::string scene = "quadrant";  // batch::kScenes (batch::scene_config)
  std::string model = "small";     // small | paper (nn::net_preset)
  int horizon = 0;                 // env steps per episode; 0 = the scene preset's
  // Fixed counts per episode instead of the scene's ranges (-1 = the scene's), for the hide-and-seek
  // scenes (quadrant, full, empty, food, dynamic-food): e.g. the paper's single-agent count-based baselines
  // (hiders 1, seekers 0). A lone agent keeps one empty, masked other-agent slot and a scene whose ramps are
  // set to 0 one empty ramp slot, so the network's inputs and checkpoints keep their types; boxes may not be
  // set to 0 in a scene that has boxes (the box type would vanish).
  int hiders = -1;
  int seekers = -1;
  int boxes = -1;
  int ramps = -1;
  // 1: every agent, box and ramp spawns in the quarter x, y in [0.2, 3.0] m (physics::SceneConfig's
  // spawn_quarter), as the paper's intrinsic-motivation baselines do; hide-and-seek scenes only.
  int spawn_quarter = 0;
  // Rollouts.
  int envs = 32;                   // game instances stepped together
  int episodes_per_iteration = 1;  // whole episodes per env per iteration
  int iterations = 100;            // total iterations of the run (a resumed run continues to this count)
  uint64_t seed = 1;
  int threads = 0;  // TBB threads for simulation and networks; 0 = every hardware thread
  // PPO (paper appendix B).
  int epochs = 4;       // passes over the rollout buffer per iteration
  int minibatches = 4;  // minibatches per epoch (each a set of BPTT chunks)
  // Minibatch size in chunks, as the paper gives it (64,000 ten-step chunks): when > 0, each epoch is split
  // into ceil(chunks / minibatch_chunks) equal minibatches and `minibatches` is not used; 0 = off.
  int minibatch_chunks = 0;
  int bptt = 10;  // BPTT truncation: steps per chunk
  // Gradient buffers of the update: at most this many threads work on one minibatch, and each is one pass
  // of zeroing and summing 4 bytes per parameter. Results depend on it, never on `threads`.
  int grad_groups = 8;
  // BPTT sequences per training chunk, the networks' unit of work; 0 = the model's (nn::default_train_chunk:
  // 4 for small, 16 for paper), which the trainer and `hns train` write in its place. Results depend on it
  // (the order of the gradient sums), never on `threads` or the rank count.
  int chunk_sequences = 0;
  // The precision of the networks' matrix products (nn/precision.hpp): "fp32", "bf16" (bf16 operands, float
  // accumulation; needs a CPU with AVX512-BF16) or "auto" (bf16 where the CPU has it, else fp32). `hns train`
  // resolves auto before writing config.json, so a run's files name the precision that ran. The RND
  // networks (intrinsic = rnd) stay fp32.
  std::string precision = "fp32";
  double lr = 3e-4;   // Adam learning rate
  double clip = 0.2;  // PPO ratio clip ε
  double entropy_coef = 0.01;
  double value_coef = 1.0;  // weight of 0.5·mean(((V - G)/std)²)
  double grad_clip = 5.0;   // global gradient-norm clip (0 = off)
  double weight_decay = 0.0;
  // Intrinsic motivation (the paper's baselines, docs/transfer.md): "none", "count" (count-based
  // exploration: count_scale / √N(S) per env step for the N-th visit of the hashed state S, counted per env,
  // given to every agent of the env; count_state: box_pos | box_full | full, the paper's three state
  // representations) or "rnd" (random network distillation: rnd_scale x the predictor's squared error on the
  // observation an agent's step reached, per agent). The reward trained on is extrinsic_coef x the game's +
  // the intrinsic one; metrics log them apart (hider_reward and seeker_reward stay the game's,
  // intrinsic_reward is the intrinsic return).
  std::string intrinsic = "none";
  std::string count_state = "box_pos";
  double count_scale = 0.1;
  double extrinsic_coef = 1.0;
  double rnd_scale = 1.0;
  double gamma = 0.998;
  double lambda = 0.95;
  // Start (Trainer::initialize_from, `hns train --init-from`): a checkpoint of the same model whose scene has
  // the same entity types (other agents, boxes, ramps; any counts), "" = from the seed. Its policy weights
  // always; the rest as the flags say.
  std::string init_from;
  int init_value = 1;        // 1: the value net's weights too (0: the value net starts from the seed)
  int init_normalizers = 1;  // 1: the observation normaliser (and, with init_value, the return normaliser)
  int init_optimizer = 0;    // 1: Adam's moments and step count
  // 1: each network's final layer norm and output layer (policy logits, value) too; 0: those start from the
  // seed, as the paper's fine-tuning reinitialises them (hns eval's default).
  int init_heads = 1;
  // Run bookkeeping.
  int checkpoint_every = 10;  // iterations between checkpoints (and one at the end)
  int inject_nan_at = 0;      // testing: poison the loss at this iteration (0 = never)

  // Throws physics::ConfigError naming the field, its value and what is allowed.
  void validate() const;
  // The precision the networks run at on a CPU with `cpu`'s features: fp32, bf16, or for auto bf16 where
  // the CPU has AVX512-BF16, else fp32. Throws physics::ConfigError for bf16 on a CPU without it (bf16 is
  // never emulated) or a value that is not one of fp32, bf16, auto.
  nn::Precision resolve_precision(const nn::CpuFeatures& cpu = nn::CpuFeatures::detect()) const;
  // Estimated peak memory of a Trainer of this config, bytes: the simulator, the rollout buffers and the
  // networks' activations per buffer row (fitted to measured resident memory; within about 25 %).
  // With `ranks` processes (MPI): the memory of the rank with the most envs.
  size_t estimated_bytes(int ranks = 1) const;
  // Envs of the rank with the most of them when `ranks` processes share the update blocks.
  int envs_per_rank(int ranks) const;
  // The game this config trains on: the scene's preset with the horizon and count overrides (the batch's
  // own fields, envs, threads and seed, at their defaults).
  batch::BatchConfig batch_config() const;
  // Its world.
  physics::WorldConfig world() const { return batch_config().world; }
  int rollout_steps() const { return world().horizon * episodes_per_iteration; }
  // BPTT chunks in the rollout buffer (every agent slot's; padding agents' chunks are left out of the
  // update).
  int64_t buffer_chunks() const {
    return int64_t(envs) * batch_config().agent_slots() * (rollout_steps() / bptt);
  }
  // Blocks of envs of the update (gradient groups; the unit a process of a data-parallel run owns):
  // min(grad_groups, envs), and no more than lets each block's share of a minibatch fill a training chunk of
  // train_chunk() sequences (smaller chunks run the network less efficiently).
  int update_blocks() const;
  // The training chunk in sequences: chunk_sequences, or where that is 0 the model's.
  int train_chunk() const;
  // Minibatches per epoch for `chunks` chunks holding real agents.
  int minibatches_for(int64_t chunks) const;

  // Sets one field from its text form ("epochs", "4"); throws ConfigError for an unknown key or bad value.
  void set(std::string_view key, std::string_view value);
  // Flat JSON object with every field, one per line, in declaration order.
  std::string to_json() const;
  // Reads a flat JSON object: each key once, a JSON string for a text field and a JSON number for a number
  // (every JSON string escape, no quoted numbers, booleans or non-JSON number forms); keys not given keep
  // their current values.
  // `origin` names the source in error messages.
  void merge_json(std::string_view text, const std::string& origin);
  // The same for the config a run was made with (its config.json, a checkpoint's): a key that version did not
  // have yet takes the value that version used (grad_groups: 16, chunk_sequences: 16, precision: fp32), not
  // today's default.
  void merge_run_json(std::string_view text, const std::string& origin);
  // Fields that change results when they differ between a checkpoint and the run resuming it.
  // Returns "" when equal, else "FIELD: checkpoint has A, this run has B".
  std::string identity_mismatch(const TrainConfig& other) const;
};

}  // namespace hns::ppo
