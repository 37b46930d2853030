// The policy and the value network together: one flat parameter buffer for both (policy slices "policy/...",
// value slices "value/..."), batched inference for the rollout, and the deterministic parallel forward +
// backward of a training minibatch.
//
// Determinism (docs/design.md "Determinism"): work is split into chunks whose sizes come from ParallelConfig,
// never from the thread count. Inference chunks are independent. Training chunks are assigned to a fixed
// number of gradient groups; each group sums its chunks' gradients in chunk order into its own buffer, and
// the groups are summed in group order. So results are bit-identical for any number of TBB threads.
//
// Masks (docs/game.md §4.6, §10.3): the policy sees entities through the visibility masks (agents_seen,
// boxes_seen, ramps_seen, sites_seen); the omniscient value net uses the presence masks (agents_present,
// boxes_present = the original's mask_ab_obs_spoof, ramps_present, sites_present), which are all 1 for slots
// that hold an entity, padding 0. Self is always 1.
#pragma once

#include "nn/entity_net.hpp"
#include "nn/precision.hpp"

#include <oneapi/tbb/enumerable_thread_specific.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

namespace hns::nn {

// Observations of `rows` agent-steps with the masks of both views (caller-owned, all float): raw, or already
// normalised (then read with ObsNormView::identity()). With an `index`, row r of the batch is row index[r] of
// the arrays (a training minibatch as a list of rollout rows, read without copying the rollout).
struct ObsBatch {
  const float* self = nullptr;            // [rows, self_features]
  const float* lidar = nullptr;           // [rows, lidar_rays]
  const float* agents = nullptr;          // [rows, max_agents - 1, agent_features]
  const float* boxes = nullptr;           // [rows, max_boxes, box_features]
  const float* ramps = nullptr;           // [rows, max_ramps, ramp_features]
  const float* sites = nullptr;           // [rows, max_sites, site_features]
  const float* agents_seen = nullptr;     // [rows, max_agents - 1] policy masks, 0/1; null = all 1
  const float* boxes_seen = nullptr;      // [rows, max_boxes]
  const float* ramps_seen = nullptr;      // [rows, max_ramps]
  const float* sites_seen = nullptr;      // [rows, max_sites]
  const float* agents_present = nullptr;  // [rows, max_agents - 1] value masks, 0/1; null = all 1
  const float* boxes_present = nullptr;   // [rows, max_boxes]
  const float* ramps_present = nullptr;   // [rows, max_ramps]
  const float* sites_present = nullptr;   // [rows, max_sites]
  const float* reset = nullptr;    // [rows] 1 where the LSTM states are zeroed before the step; null = never
  const int32_t* index = nullptr;  // [rows] the array row of each batch row; null = row r is row r

  // The same batch starting at row `first` (of the index, if there is one).
  ObsBatch rows_from(size_t first, const ObsShape& shape) const;
  NetInputs policy_inputs() const;
  NetInputs value_inputs() const;
};

// Rows of an inference chunk are padded to a multiple of this: Eigen computes a remainder of its 4-row panels
// by another kernel, whose sums round differently, and a row's outputs must not depend on its chunk.
inline constexpr int kActRowAlign = 8;

// Fixed work partition (independent of the thread count).
struct ParallelConfig {
  int infer_chunk_agents = 64;  // agents per inference task
  // BPTT sequences per training chunk (the unit of the forward and backward passes); 0: the network's
  // default_train_chunk. Results depend on it (the order of the gradient sums), never on the threads.
  int train_chunk_sequences = 0;
  // Gradient buffers: the parallel width of training (two tasks each, the policy and the value network), and
  // per minibatch one zeroing and one summing pass over groups x parameters floats (16 groups cost about 5 %
  // of a quadrant paper iteration on 2 cores over 8).
  int grad_groups = 8;
  // bf16 with the vdpbf16ps kernel: each network's weight gradients summed over several chunks by one
  // product (nn/products.hpp GradStage); the same bits as one product per chunk (false: that, for the
  // tests that compare the two).
  bool stage_weight_grads = true;
};

// The training chunk for a network, measured on a 2-core AMD Zen 5 (src/nn/README.md "The training chunk per
// model"): 4 sequences for networks as narrow as the `small` preset (embedding <= 64), whose chunk's
// activations then stay near the core (in fp32 clearly the fastest; in bf16 4-12 are within that host's
// noise, all well ahead of 16), and 16 for wider ones such as `paper`, where each chunk's passes over a
// gradient 3.4 times the size outweigh that.
int default_train_chunk(const NetConfig& cfg);

// What the loss sees of one training chunk: rows [first_row, first_row + rows) of the minibatch.
struct ChunkOutputs {
  int first_row = 0;
  int rows = 0;
  CMat logits;                   // [rows, num_logits] policy logits
  const float* value = nullptr;  // [rows] value head (normalised value)
};
// What the loss must write for that chunk: the gradient of the minibatch loss w.r.t. the outputs.
struct ChunkGrads {
  Mat d_logits;              // [rows, num_logits]
  float* d_value = nullptr;  // [rows]
};
// Called once per chunk, concurrently from several threads: it must only touch its own rows. `stats` (zeroed)
// receives per-chunk loss statistics, which are summed over chunks in order.
using LossFn = std::function<void(const ChunkOutputs&, const ChunkGrads&, std::span<double> stats)>;

class ActorCritic {
 public:
  explicit ActorCritic(const NetConfig& cfg, ParallelConfig parallel = {});
  ~ActorCritic();
  ActorCritic(const ActorCritic&) = delete;
  ActorCritic& operator=(const ActorCritic&) = delete;

  // The parameter layout an ActorCritic of this config has (to read another run's parameters by name).
  static ParamLayout layout_of(const NetConfig& cfg);

  const NetConfig& config() const { return cfg_; }
  const ParallelConfig& parallel() const { return par_; }
  // The non-const access marks the packed bf16 weights stale: the next act() repacks them (forward_backward
  // always packs). Change the values only through a reference obtained after the last act().
  ParamStore& params() {
    packed_stale_ = true;
    return params_;
  }
  const ParamStore& params() const { return params_; }
  const EntityNet& policy() const { return policy_; }
  const EntityNet& value() const { return value_; }
  const CategoricalHeads& heads() const { return heads_; }
  size_t num_params() const { return params_.layout().num_params(); }
  // The precision of both networks' matrix products (nn/precision.hpp); fp32 until set. Throws
  // std::invalid_argument for bf16 on a CPU without a native bf16 dot product.
  void set_precision(Precision p);
  Precision precision() const { return precision_; }
  // LSTM state floats per agent and per network: (c, h).
  int state_width() const { return 2 * cfg_.lstm; }
  // Multiply-add flops of policy + value forward over `rows` agent-steps (backward: twice that).
  double forward_flops(int rows) const { return policy_.forward_flops(rows) + value_.forward_flops(rows); }
  // The same counting only the entities each network sees (ObsBatch's seen and present masks).
  double forward_flops_used(const ObsBatch& obs, int rows) const {
    return policy_.forward_flops_used(obs.policy_inputs(), rows) +
           value_.forward_flops_used(obs.value_inputs(), rows);
  }

  // Outputs of one inference step ([agents, ...]; logits may be null).
  struct ActOutputs {
    int32_t* actions = nullptr;  // [agents, num_heads] sampled actions
    float* logp = nullptr;       // [agents] their summed log-probability
    float* value = nullptr;      // [agents] value head (normalised)
    float* logits = nullptr;     // [agents, num_logits] optional
  };
  // One environment step for `agents` agents (steps = 1). policy_state, value_state [agents, state_width()]
  // are read and replaced by the new states (obs.reset zeroes them first). uniforms [agents, num_heads] in
  // [0, 1). Parallel inside; one call at a time per ActorCritic (act and forward_backward share its packed
  // LSTM weights), like forward_backward.
  void act(const ObsNormView& norm, const ObsBatch& obs, int agents, float* policy_state, float* value_state,
           const float* uniforms, const ActOutputs& out) const;

  // Forward + loss + backward over a minibatch of `sequences` BPTT sequences of `steps` steps (rows
  // sequence-major, row = b * steps + t). policy_state0, value_state0 [sequences, state_width()]: the states
  // entering step 0 (null: zeros). Writes the summed gradients to grads_out (a buffer of
  // params().buffer_floats(); may be params().grads()) and the chunk-summed loss statistics to stats.
  // Gradient groups: by default the chunks are split into min(grad_groups, chunks) contiguous groups; with
  // group_sequences ([groups + 1], non-decreasing, from 0 to `sequences`) group g is sequences
  // [group_sequences[g], group_sequences[g + 1]) (possibly none), cut into chunks from its own start. Either
  // way each group sums its chunks in order, the groups are summed in group order, and the statistics are
  // summed in chunk order (group by group).
  void forward_backward(const ObsNormView& norm, const ObsBatch& obs, int sequences, int steps,
                        const float* policy_state0, const float* value_state0, const LossFn& loss,
                        std::span<double> stats, float* grads_out, std::span<const int> group_sequences = {});
  // The same in two parts, for a sum that goes on in other processes: compute_groups() leaves every group's
  // gradient and every chunk's statistics (`nstats` each) here; sum_groups() writes out[i] = before[i -
  // begin] (or nothing if null) + group 0 + group 1 + ... in that order, for i in [begin, end), and zeroes
  // what it has read (the next compute_groups() accumulates into zeros without a pass of its own to clear
  // the groups). So each float is summed once per compute_groups(): a second sum of a range reads zeros.
  // Ranges never summed are safe: unless every float was summed, the next compute_groups() clears the
  // groups itself.
  void compute_groups(const ObsNormView& norm, const ObsBatch& obs, int sequences, int steps,
                      const float* policy_state0, const float* value_state0, const LossFn& loss,
                      size_t nstats, std::span<const int> group_sequences = {});
  void sum_groups(size_t begin, size_t end, const float* before, float* out);
  // [chunks, nstats] of the last compute_groups(), chunk by chunk (group by group).
  std::span<const double> chunk_stats() const { return chunk_stats_; }

 private:
  struct ThreadWork;
  ThreadWork& local_work(tbb::enumerable_thread_specific<std::unique_ptr<ThreadWork>>& ets, int sequences,
                         int steps) const;

  NetConfig cfg_;
  ParallelConfig par_;
  EntityNet policy_;  // declared before params_: params_'s initialiser builds both nets' layout
  EntityNet value_;
  CategoricalHeads heads_;
  ParamStore params_;
  mutable tbb::enumerable_thread_specific<std::unique_ptr<ThreadWork>> infer_work_;
  // Training workspaces: a gradient group takes one at its start and gives it back at its end, so no more
  // exist than groups ever ran at once (min(threads, groups)), whichever threads ran them over a run.
  struct WorkPool {
    std::mutex mutex;
    std::vector<std::unique_ptr<ThreadWork>> idle;
  };
  std::unique_ptr<WorkPool> train_pool_;  // (made by the constructor, where ThreadWork is complete)
  std::unique_ptr<ThreadWork> take_train_work(int sequences, int steps);
  void give_back(std::unique_ptr<ThreadWork> w);
  // Packs both LSTMs' recurrent kernels for the current params (the forward's only, or both).
  void pack_lstms(bool for_backward) const;
  // The weights a pass reads at the current precision, packed as needed: fp32, the LSTMs' recurrent kernels;
  // bf16, every product matrix (and, for a backward pass, their transposes).
  Weights prepare_weights(bool for_backward) const;

  std::vector<FloatBuffer> group_grads_;  // [groups][buffer_floats]
  // 1 where a group's buffer may hold gradients (written by compute_groups() and not yet all summed).
  std::vector<uint8_t> group_dirty_;
  std::vector<uint8_t> group_clear_;  // compute_groups(): 1 where a group's buffer must be zeroed first
  int summed_groups_ = 0;             // the groups sum_groups() reads and zeroes: the last compute_groups()'s
  // Floats sum_groups() has zeroed since the last compute_groups() (the ranges of one chain sum are
  // disjoint; all of them: every group is clear again).
  std::unique_ptr<std::atomic<size_t>> zeroed_floats_ = std::make_unique<std::atomic<size_t>>(0);
  struct Chunk {
    int first_seq = 0, sequences = 0;
  };
  std::vector<Chunk> chunks_;      // of the current forward_backward, group by group
  std::vector<int> group_chunks_;  // [groups + 1] chunk ranges of the groups
  // The LSTMs' recurrent kernels packed once per act() or forward_backward() call (the params do not change
  // during one), shared by every chunk: [policy, value], each two packed_floats() (W_h, W_h^T).
  mutable FloatBuffer lstm_packed_buf_[2];
  mutable Lstm::Packed lstm_packed_[2];
  std::vector<double> chunk_stats_;  // [chunks, stats]
  Precision precision_ = Precision::kFp32;
  mutable std::unique_ptr<PackedWeights> packed_;  // bf16 forms of the product matrices
  mutable bool packed_stale_ = true;               // packed_ does not hold the current values
};

}  // namespace hns::nn
