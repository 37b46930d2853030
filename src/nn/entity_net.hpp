// The hide-and-seek policy and value networks (docs/game.md §10.3 variant A; same structure, separate
// weights):
//
//   self [S] ---------------------------------------------.
//   lidar [L] -> circ conv (K filters, kernel 3, relu) -> main = [self, conv] (S + L*K)
//   main -> dense D relu ------------------------------------------------------------> self entity ---.
//   [main, agent_j] -> dense D relu (per type; boxes, ramps likewise) -> entities [A + B + R + 1, D] <-'
//   entities -> residual self-attention (heads x D/heads, pre and post layer norm), masked
//            -> masked mean pool -> concat [self entity embedding, pooled] (2D) -> layer norm
//            -> dense H relu -> layer norm -> LSTM U -> layer norm -> heads
//   policy heads: 37 logits (3 x 11 movement, 2 grab, 2 lock); value head: 1 (normalised value).
//
// Observations are normalised inside forward (fused normalise + clip kernel, while gathering the rows) unless
// the caller normalised them already (ObsNormView::identity(): the trainer does it once per rollout row, for
// both networks); entities with mask 0 are excluded from attention (as keys and queries) and from pooling, so
// their features never reach an output. The policy uses the visibility masks, the value net
// the omniscient ones (docs/game.md §4.6; see nn/actor_critic.hpp).
//
// Rows are agent-steps, sequence-major: row = b * steps + t for `sequences` sequences of `steps` steps
// (inference: steps = 1, one row per agent). A Workspace holds every activation for one (sequences, steps)
// shape.
#pragma once

#include "nn/heads.hpp"
#include "nn/layers.hpp"
#include "nn/obs_normalizer.hpp"

#include <string>
#include <string_view>
#include <vector>

namespace hns::nn {

// Observation sizes: parameters, so the simulator's configuration plugs in (defaults: the `full` scene with
// yaw as cos/sin, docs/game.md §14.1).
struct ObsShape {
  int self_features =
      11;  // x_self: position 3, yaw cos/sin 2, velocity 3, angular velocity 1, team bit, prep obs
  int max_agents = 6;       // agents per env at most; each agent sees the other max_agents - 1
  int agent_features = 11;  // per other agent: same quantities as x_self
  int max_boxes = 9;
  int box_features = 15;  // position 3, yaw cos/sin 2, velocity 3, angular velocity 1, size 3, lock 3
  int max_ramps = 2;
  int ramp_features = 15;  // as boxes (size padded with zeros)
  // Sites: the fourth entity type, only in the scenes that have one (0 elsewhere, and the network then has
  // no parameters for it): blueprint's construction sites (centre 3 + 4 corners x 3 = 15 features).
  int max_sites = 0;
  int site_features = 0;
  int lidar_rays = 30;

  int num_other_agents() const { return max_agents - 1; }
  // Entities attended over: other agents, boxes, ramps, sites, self.
  int num_entities() const { return num_other_agents() + max_boxes + max_ramps + max_sites + 1; }
};

struct NetConfig {
  ObsShape obs;
  int lidar_filters = 9;  // circular conv filters
  int lidar_kernel = 3;
  int embed = 128;                                     // entity embedding width = attention width (n_embd)
  int heads = 4;                                       // attention heads (embed / heads features each)
  int dense = 256;                                     // dense layer after pooling
  int lstm = 256;                                      // LSTM units; 0: no LSTM (the RND networks)
  std::vector<int> action_heads = {11, 11, 11, 2, 2};  // choices per categorical action head
};

// Model presets: "paper" (embedding 128, attention 4 x 32, dense 256, LSTM 256; about 1.6 M parameters for
// policy
// + value) and "small" (embedding 64, attention 2 x 32, dense 128, LSTM 128). Throws std::invalid_argument
// naming the allowed values for anything else.
NetConfig net_preset(std::string_view name);
std::vector<std::string> net_preset_names();

// Observations and masks of `rows` agent-steps for one network (caller-owned; all float): raw, or normalised
// already (ObsNormView::identity()). With an `index`, row r is row index[r] of every array.
struct NetInputs {
  const float* self = nullptr;         // [rows, self_features]
  const float* lidar = nullptr;        // [rows, lidar_rays], m
  const float* agents = nullptr;       // [rows, max_agents - 1, agent_features]
  const float* boxes = nullptr;        // [rows, max_boxes, box_features]
  const float* ramps = nullptr;        // [rows, max_ramps, ramp_features]
  const float* sites = nullptr;        // [rows, max_sites, site_features]
  const float* agents_mask = nullptr;  // [rows, max_agents - 1], 0/1; null = all 1
  const float* boxes_mask = nullptr;   // [rows, max_boxes]
  const float* ramps_mask = nullptr;   // [rows, max_ramps]
  const float* sites_mask = nullptr;   // [rows, max_sites]
  const float* reset = nullptr;    // [rows], 1 where the LSTM state is zeroed before the step; null = never
  const int32_t* index = nullptr;  // [rows] array row of each row; null = the identity
};

// The output layer: the policy's logits, the value, or RND's 64-wide random projection (kRnd, paper's
// appendix: the value network without its LSTM, projecting to 64 outputs).
enum class NetHead { kPolicy, kValue, kRnd };
inline constexpr int kRndOutputs = 64;

class EntityNet {
 public:
  // Every activation of one forward pass and the backward scratch, for sequences x steps rows.
  struct Buffers {
    NetConfig cfg;
    int sequences = 0, steps = 0, outputs = 0;
    float* main = nullptr;        // [rows, S + L*K] normalised self, then conv features
    float* lidar_n = nullptr;     // [rows, L] normalised lidar
    float* agents_n = nullptr;    // [rows * A, Fa] normalised
    float* boxes_n = nullptr;     // [rows * B, Fb]
    float* ramps_n = nullptr;     // [rows * R, Fr]
    float* sites_n = nullptr;     // [rows * C, Fc]
    float* mask = nullptr;        // [rows, E] entity mask (agents, boxes, ramps, sites, self = 1)
    float* reset = nullptr;       // [rows] the rows' reset flags (0 without any)
    float* x = nullptr;           // [rows * E, D] entity embeddings
    float* embed_rows = nullptr;  // [rows, D] scratch
    float* embed_ent = nullptr;   // [rows * max(A, B, R, C), D] scratch
    SelfAttention::Buffers sa;
    float* sa_out = nullptr;       // [rows * E, D]
    float* cat = nullptr;          // [rows, 2D] self embedding, pooled
    float* cat_n = nullptr;        // [rows, 2D] layer-normed
    float* cat_stats = nullptr;    // [rows, 2]
    float* dense_a = nullptr;      // [rows, H] relu(dense)
    float* dense_n = nullptr;      // [rows, H] layer-normed
    float* dense_stats = nullptr;  // [rows, 2]
    Lstm::Buffers lstm;
    float* out_n = nullptr;      // [rows, U] layer-normed LSTM output
    float* out_stats = nullptr;  // [rows, 2]
    float* head = nullptr;       // [rows, outputs]
    float* d_out_n = nullptr;    // [rows, U]
    float* d_h = nullptr;        // [rows, U]
    float* d_dense_n = nullptr;  // [rows, H]
    float* d_cat_n = nullptr;    // [rows, 2D]
    float* d_cat = nullptr;      // [rows, 2D]
    float* d_sa_out = nullptr;   // [rows * E, D]
    float* d_x = nullptr;        // [rows * E, D]
    float* d_main = nullptr;     // [rows, S + L*K]
    Buffers() = default;
    Buffers(const NetConfig& cfg, int outputs, int sequences, int steps);
    void bind(Arena& arena);
  };
  using Work = Workspace<Buffers>;

  EntityNet() = default;
  // Registers this net's parameters under "<prefix>/...".
  EntityNet(const NetConfig& cfg, NetHead head, ParamLayout& layout, const std::string& prefix);

  const NetConfig& config() const { return cfg_; }
  NetHead head_kind() const { return head_kind_; }
  int num_outputs() const { return head_.out(); }
  int main_width() const { return cfg_.obs.self_features + conv_.out_width(); }
  // Width of the last hidden layer: the LSTM's, or the dense layer's without one.
  int out_width() const { return cfg_.lstm > 0 ? cfg_.lstm : cfg_.dense; }
  // Workspace for chunks of up to `sequences` sequences of `steps` steps.
  Work make_workspace(int sequences, int steps) const { return Work(cfg_, num_outputs(), sequences, steps); }
  // Floats such a workspace holds (counted without allocating): what memory estimates are built from.
  size_t workspace_floats(int sequences, int steps) const {
    Buffers b(cfg_, num_outputs(), sequences, steps);
    Arena counter;
    b.bind(counter);
    return counter.used();
  }
  // Multiply-add flops of one forward pass over `rows` agent-steps (GEMMs, conv and attention products);
  // a backward pass is counted as twice that.
  double forward_flops(int rows) const;
  // The same counting only unmasked entities (in's masks; null masks count every slot): the work that
  // decides the outputs. Attention skips masked entities; the embeddings compute every slot. Contiguous rows
  // only (in.index null).
  double forward_flops_used(const NetInputs& in, int rows) const;

  // Forward over sequences x steps rows (without an LSTM every row is on its own: any split will do).
  // state_in / state_out: LSTM state [sequences, 2 * lstm] (c, h);
  // state_in null means zeros, state_out null means not written. Outputs: output(ws).
  // lstm_packed: the LSTM's recurrent kernel packed by pack_lstm() for these params (null: packed per call).
  void forward(const Weights& params, const ObsNormView& norm, const NetInputs& in, int sequences, int steps,
               const float* state_in, float* state_out, Work& ws,
               const Lstm::Packed* lstm_packed = nullptr) const;
  // [rows, num_outputs] of the last forward.
  CMat output(const Work& ws, int rows) const { return {ws.bufs().head, rows, num_outputs()}; }
  // Backward of the last forward on ws: d_output [rows, num_outputs]; accumulates into grads.
  void backward(const Weights& params, float* grads, int sequences, int steps, CMat d_output, Work& ws,
                const Lstm::Packed* lstm_packed = nullptr) const;
  // The LSTM's recurrent kernel packed once for many forward/backward calls with the same params.
  size_t lstm_packed_floats() const { return lstm_.packed_floats(); }
  void pack_lstm(const float* params, bool for_backward, Lstm::Packed& out) const {
    lstm_.pack(params, for_backward, out);
  }

 private:
  NetConfig cfg_;
  NetHead head_kind_ = NetHead::kPolicy;
  CircConv1d conv_;
  Dense self_embed_;
  EntityEmbedding agents_embed_;
  EntityEmbedding boxes_embed_;
  EntityEmbedding ramps_embed_;
  EntityEmbedding sites_embed_;
  SelfAttention attention_;
  LayerNorm cat_norm_;
  Dense dense_;
  LayerNorm dense_norm_;
  Lstm lstm_;
  LayerNorm out_norm_;
  Dense head_;
};

}  // namespace hns::nn
