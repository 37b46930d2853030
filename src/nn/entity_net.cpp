#include "nn/entity_net.hpp"

#include "nn/kernels.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>

namespace hns::nn {

NetConfig net_preset(std::string_view name) {
  NetConfig cfg;
  if (name == "paper") return cfg;
  if (name == "small") {
    cfg.embed = 64;
    cfg.heads = 2;
    cfg.dense = 128;
    cfg.lstm = 128;
    return cfg;
  }
  throw std::invalid_argument("unknown model preset '" + std::string(name) + "' (allowed: paper, small)");
}

std::vector<std::string> net_preset_names() {
  return {"paper", "small"};
}

EntityNet::Buffers::Buffers(const NetConfig& c, int outputs_, int sequences_, int steps_)
    : cfg(c), sequences(sequences_), steps(steps_), outputs(outputs_) {
  const int rows = sequences * steps;
  sa = SelfAttention::Buffers(rows, cfg.obs.num_entities(), cfg.embed, cfg.heads);
  if (cfg.lstm > 0) lstm = Lstm::Buffers(sequences, steps, cfg.dense, cfg.lstm);
}

void EntityNet::Buffers::bind(Arena& arena) {
  const ObsShape& o = cfg.obs;
  const size_t rows = static_cast<size_t>(sequences) * steps;
  const size_t m = o.self_features + static_cast<size_t>(o.lidar_rays) * cfg.lidar_filters;
  const size_t e = o.num_entities();
  const size_t d = cfg.embed;
  const size_t max_count = std::max({o.num_other_agents(), o.max_boxes, o.max_ramps, o.max_sites, 1});
  main = arena.take(rows * m);
  lidar_n = arena.take(rows * o.lidar_rays);
  agents_n = arena.take(rows * o.num_other_agents() * o.agent_features);
  boxes_n = arena.take(rows * o.max_boxes * o.box_features);
  ramps_n = arena.take(rows * o.max_ramps * o.ramp_features);
  sites_n = arena.take(rows * o.max_sites * o.site_features);
  mask = arena.take(rows * e);
  reset = arena.take(rows);
  x = arena.take(rows * e * d);
  embed_rows = arena.take(rows * d);
  embed_ent = arena.take(rows * max_count * d);
  sa.bind(arena);
  sa_out = arena.take(rows * e * d);
  cat = arena.take(rows * 2 * d);
  cat_n = arena.take(rows * 2 * d);
  cat_stats = arena.take(rows * 2);
  dense_a = arena.take(rows * cfg.dense);
  dense_n = arena.take(rows * cfg.dense);
  dense_stats = arena.take(rows * 2);
  const size_t u = cfg.lstm > 0 ? cfg.lstm : cfg.dense;  // the width the output layer norm sees
  if (cfg.lstm > 0) lstm.bind(arena);
  out_n = arena.take(rows * u);
  out_stats = arena.take(rows * 2);
  head = arena.take(rows * outputs);
  d_out_n = arena.take(rows * u);
  d_h = arena.take(rows * u);
  d_dense_n = arena.take(rows * cfg.dense);
  d_cat_n = arena.take(rows * 2 * d);
  d_cat = arena.take(rows * 2 * d);
  d_sa_out = arena.take(rows * e * d);
  d_x = arena.take(rows * e * d);
  d_main = arena.take(rows * m);
}

EntityNet::EntityNet(const NetConfig& cfg, NetHead head, ParamLayout& layout, const std::string& prefix)
    : cfg_(cfg), head_kind_(head) {
  const ObsShape& o = cfg.obs;
  HNS_NN_CHECK(o.self_features > 0 && o.lidar_rays > 0 && o.max_agents >= 1, "observation shape is empty");
  HNS_NN_CHECK(cfg.embed > 0 && cfg.dense > 0 && cfg.lstm >= 0, "network widths must be positive");
  const std::string p = prefix + "/";
  conv_ = CircConv1d(layout, p + "lidar_conv", o.lidar_rays, 1, cfg.lidar_filters, cfg.lidar_kernel);
  const int m = main_width();
  self_embed_ = Dense(layout, p + "embed_self", m, cfg.embed, Activation::kRelu);
  if (o.num_other_agents() > 0)
    agents_embed_ = EntityEmbedding(layout, p + "embed_agents", m, o.agent_features, cfg.embed);
  if (o.max_boxes > 0)
    boxes_embed_ = EntityEmbedding(layout, p + "embed_boxes", m, o.box_features, cfg.embed);
  if (o.max_ramps > 0)
    ramps_embed_ = EntityEmbedding(layout, p + "embed_ramps", m, o.ramp_features, cfg.embed);
  HNS_NN_CHECK(o.max_sites == 0 || o.site_features > 0, "sites without features");
  if (o.max_sites > 0)
    sites_embed_ = EntityEmbedding(layout, p + "embed_sites", m, o.site_features, cfg.embed);
  attention_ = SelfAttention(layout, p + "attention", cfg.embed, cfg.heads, true, true);
  cat_norm_ = LayerNorm(layout, p + "cat_norm", 2 * cfg.embed);
  dense_ = Dense(layout, p + "dense", 2 * cfg.embed, cfg.dense, Activation::kRelu);
  dense_norm_ = LayerNorm(layout, p + "dense_norm", cfg.dense);
  const int u = out_width();
  if (cfg.lstm > 0) lstm_ = Lstm(layout, p + "lstm", cfg.dense, cfg.lstm);
  out_norm_ = LayerNorm(layout, p + "out_norm", u);
  if (head == NetHead::kPolicy) {
    int logits = 0;
    for (int s : cfg.action_heads) logits += s;
    head_ = Dense(layout, p + "logits", u, logits, Activation::kNone, {Init::kNormc, 0.01f});
  } else if (head == NetHead::kValue) {
    head_ = Dense(layout, p + "value", u, 1, Activation::kNone);
  } else {
    head_ = Dense(layout, p + "projection", u, kRndOutputs, Activation::kNone);
  }
}

namespace {

// The array row of row r of the inputs.
ptrdiff_t in_row(const NetInputs& in, int r) {
  return in.index != nullptr ? in.index[r] : r;
}

// Entities of one type with mask 1 over rows x count slots (all of them for a null mask).
double count_unmasked(const float* mask, int rows, int count) {
  if (mask == nullptr) return double(rows) * count;
  double n = 0;
  for (ptrdiff_t i = 0; i < ptrdiff_t(rows) * count; ++i) n += mask[i] != 0.0f;
  return n;
}

}  // namespace

double EntityNet::forward_flops(int rows) const {
  const ObsShape& o = cfg_.obs;
  double f = conv_.flops(rows) + self_embed_.flops(rows);
  if (o.num_other_agents() > 0) f += agents_embed_.flops(rows, double(rows) * o.num_other_agents());
  if (o.max_boxes > 0) f += boxes_embed_.flops(rows, double(rows) * o.max_boxes);
  if (o.max_ramps > 0) f += ramps_embed_.flops(rows, double(rows) * o.max_ramps);
  if (o.max_sites > 0) f += sites_embed_.flops(rows, double(rows) * o.max_sites);
  const double e = o.num_entities();
  f += attention_.flops(rows * e, rows * e * e);
  f += dense_.flops(rows) + (cfg_.lstm > 0 ? lstm_.flops(rows) : 0.0) + head_.flops(rows);
  return f;
}

double EntityNet::forward_flops_used(const NetInputs& in, int rows) const {
  HNS_NN_CHECK(in.index == nullptr, "forward_flops_used counts contiguous rows only");
  const ObsShape& o = cfg_.obs;
  const int na = o.num_other_agents(), nb = o.max_boxes, nr = o.max_ramps, nc = o.max_sites;
  double f = conv_.flops(rows) + self_embed_.flops(rows);
  if (na > 0) f += agents_embed_.flops(rows, count_unmasked(in.agents_mask, rows, na));
  if (nb > 0) f += boxes_embed_.flops(rows, count_unmasked(in.boxes_mask, rows, nb));
  if (nr > 0) f += ramps_embed_.flops(rows, count_unmasked(in.ramps_mask, rows, nr));
  if (nc > 0) f += sites_embed_.flops(rows, count_unmasked(in.sites_mask, rows, nc));
  double entities = 0, pairs = 0;
  for (int r = 0; r < rows; ++r) {
    const double n =
        1 + count_unmasked(in.agents_mask == nullptr ? nullptr : in.agents_mask + ptrdiff_t(r) * na, 1, na) +
        count_unmasked(in.boxes_mask == nullptr ? nullptr : in.boxes_mask + ptrdiff_t(r) * nb, 1, nb) +
        count_unmasked(in.ramps_mask == nullptr ? nullptr : in.ramps_mask + ptrdiff_t(r) * nr, 1, nr) +
        count_unmasked(in.sites_mask == nullptr ? nullptr : in.sites_mask + ptrdiff_t(r) * nc, 1, nc);
    entities += n;
    pairs += n * n;
  }
  f += attention_.flops(entities, pairs);
  f += dense_.flops(rows) + (cfg_.lstm > 0 ? lstm_.flops(rows) : 0.0) + head_.flops(rows);
  return f;
}

// Extra, deterministic work per row of every forward pass in builds configured with HNS_INJECT_NN_WORK > 0:
// tools/perf-gate's tests use such a build as a known slowdown of the network path. A no-op otherwise.
#ifndef HNS_INJECT_NN_WORK
#define HNS_INJECT_NN_WORK 0
#endif
namespace {
void inject_nn_work(int rows) {
  if constexpr (HNS_INJECT_NN_WORK > 0) {
    static volatile uint64_t sink = 0;
    uint64_t x = sink | 1;
    for (long i = 0; i < long(HNS_INJECT_NN_WORK) * rows; ++i) {
      x ^= x << 13;
      x ^= x >> 7;
      x ^= x << 17;
    }
    sink = x;
  }
}
}  // namespace

void EntityNet::forward(const Weights& params, const ObsNormView& norm, const NetInputs& in, int sequences,
                        int steps, const float* state_in, float* state_out, Work& ws,
                        const Lstm::Packed* lstm_packed) const {
  Buffers& b = ws.bufs();
  const ObsShape& o = cfg_.obs;
  const int rows = sequences * steps;
  assert(sequences <= b.sequences && steps == b.steps);
  inject_nn_work(rows);
  const int s = o.self_features, l = o.lidar_rays, m = main_width(), d = cfg_.embed, e = o.num_entities();
  const int na = o.num_other_agents(), nb = o.max_boxes, nr = o.max_ramps, nc = o.max_sites;
  HNS_NN_CHECK(in.self != nullptr && in.lidar != nullptr && (na == 0 || in.agents != nullptr) &&
                   (nb == 0 || in.boxes != nullptr) && (nr == 0 || in.ramps != nullptr) &&
                   (nc == 0 || in.sites != nullptr),
               "an entity type of the observation shape has no input array");

  // Gather the rows (through in.index, if any), normalising and clipping unless they are normalised
  // already: self into main[:, 0:S), lidar, and each entity type. A masked entity's features are gathered
  // like the others; nothing downstream reads them (attention and pooling skip it).
  const bool raw = !norm.is_identity();
  auto gather = [&](const float* src, int key, int per_row, int features, float* dst, ptrdiff_t dst_stride) {
    for (int r = 0; r < rows; ++r) {
      const float* from = src + in_row(in, r) * per_row;
      float* to = dst + r * dst_stride;
      if (raw) {
        kernels::normalize_obs(from, norm.mean[key], norm.inv_std[key], nullptr, per_row / features, features,
                               to);
      } else {
        std::memcpy(to, from, sizeof(float) * per_row);
      }
    }
  };
  gather(in.self, kObsSelf, s, s, b.main, m);
  gather(in.lidar, kObsLidar, l, l, b.lidar_n, l);
  if (na > 0)
    gather(in.agents, kObsAgents, na * o.agent_features, o.agent_features, b.agents_n, na * o.agent_features);
  if (nb > 0)
    gather(in.boxes, kObsBoxes, nb * o.box_features, o.box_features, b.boxes_n, nb * o.box_features);
  if (nr > 0)
    gather(in.ramps, kObsRamps, nr * o.ramp_features, o.ramp_features, b.ramps_n, nr * o.ramp_features);
  if (nc > 0)
    gather(in.sites, kObsSites, nc * o.site_features, o.site_features, b.sites_n, nc * o.site_features);

  // Entity mask [agents, boxes, ramps, sites, self]; the reset flags of the rows.
  for (int r = 0; r < rows; ++r) {
    const ptrdiff_t src = in_row(in, r);
    float* mk = b.mask + static_cast<ptrdiff_t>(r) * e;
    for (int j = 0; j < na; ++j) mk[j] = in.agents_mask != nullptr ? in.agents_mask[src * na + j] : 1.0f;
    for (int j = 0; j < nb; ++j) mk[na + j] = in.boxes_mask != nullptr ? in.boxes_mask[src * nb + j] : 1.0f;
    for (int j = 0; j < nr; ++j)
      mk[na + nb + j] = in.ramps_mask != nullptr ? in.ramps_mask[src * nr + j] : 1.0f;
    for (int j = 0; j < nc; ++j)
      mk[na + nb + nr + j] = in.sites_mask != nullptr ? in.sites_mask[src * nc + j] : 1.0f;
    mk[e - 1] = 1.0f;
    b.reset[r] = in.reset != nullptr ? in.reset[src] : 0.0f;
  }

  // Lidar conv into main[:, S:), then the embeddings of self and of every entity type.
  const CMat main(b.main, rows, m);
  conv_.forward(params, CMat(b.lidar_n, rows, l), Mat(b.main + s, rows, conv_.out_width(), m));
  // The self embedding and every entity type's x_self part multiply main: in bf16 it is converted once.
  const SharedRows main_rows = convert_shared(params, main);
  const EntitySlots self_slot{b.x, rows, e, d, e - 1, 1};
  self_embed_.forward(params, main_rows, self_slot.slot(0));
  const Mat scratch(b.embed_rows, rows, d);
  if (na > 0)
    agents_embed_.forward(params, main_rows, CMat(b.agents_n, rows * na, o.agent_features),
                          {b.x, rows, e, d, 0, na}, scratch);
  if (nb > 0)
    boxes_embed_.forward(params, main_rows, CMat(b.boxes_n, rows * nb, o.box_features),
                         {b.x, rows, e, d, na, nb}, scratch);
  if (nr > 0)
    ramps_embed_.forward(params, main_rows, CMat(b.ramps_n, rows * nr, o.ramp_features),
                         {b.x, rows, e, d, na + nb, nr}, scratch);
  if (nc > 0)
    sites_embed_.forward(params, main_rows, CMat(b.sites_n, rows * nc, o.site_features),
                         {b.x, rows, e, d, na + nb + nr, nc}, scratch);

  // Masked residual self-attention, masked mean pool, concat with the self embedding, layer norm.
  attention_.forward(params, CMat(b.x, rows * e, d), b.mask, e, b.sa, Mat(b.sa_out, rows * e, d));
  masked_mean_pool(CMat(b.sa_out, rows * e, d), b.mask, e, Mat(b.cat + d, rows, d, 2 * d));
  for (int r = 0; r < rows; ++r)
    std::memcpy(b.cat + static_cast<ptrdiff_t>(r) * 2 * d, self_slot.at(r, 0), sizeof(float) * d);
  cat_norm_.forward(params, CMat(b.cat, rows, 2 * d), Mat(b.cat_n, rows, 2 * d), b.cat_stats);

  // Dense + ReLU fused with the following layer norm.
  const Mat dense_a(b.dense_a, rows, cfg_.dense);
  dense_.forward_linear(params, CMat(b.cat_n, rows, 2 * d), dense_a);
  dense_norm_.forward_fused(params, dense_a, params.values + dense_.b_offset(), Activation::kRelu, dense_a,
                            Mat(b.dense_n, rows, cfg_.dense), b.dense_stats);

  // LSTM (if any), layer norm, head.
  const int u = out_width();
  const float* last_hidden = b.dense_n;
  if (cfg_.lstm > 0) {
    lstm_.forward(params, CMat(b.dense_n, rows, cfg_.dense), sequences, steps, b.reset, state_in, b.lstm,
                  state_out, lstm_packed);
    last_hidden = b.lstm.h;
  }
  out_norm_.forward(params, CMat(last_hidden, rows, u), Mat(b.out_n, rows, u), b.out_stats);
  head_.forward(params, CMat(b.out_n, rows, u), Mat(b.head, rows, num_outputs()));
}

void EntityNet::backward(const Weights& params, float* grads, int sequences, int steps, CMat d_output,
                         Work& ws, const Lstm::Packed* lstm_packed) const {
  Buffers& b = ws.bufs();
  const ObsShape& o = cfg_.obs;
  const int rows = sequences * steps;
  assert(sequences <= b.sequences && steps == b.steps && d_output.rows == rows);
  const int s = o.self_features, l = o.lidar_rays, m = main_width(), d = cfg_.embed, e = o.num_entities();
  const int na = o.num_other_agents(), nb = o.max_boxes, nr = o.max_ramps, nc = o.max_sites;
  const int u = out_width(), h = cfg_.dense;

  // Head, output layer norm, LSTM (through time; without one, the layer norm's input is the dense layer's
  // output), dense + ReLU + layer norm, concat layer norm.
  head_.backward_preact(params, grads, CMat(b.out_n, rows, u), d_output, Mat(b.d_out_n, rows, u), false);
  if (cfg_.lstm > 0) {
    out_norm_.backward(params, grads, CMat(b.lstm.h, rows, u), b.out_stats, CMat(b.d_out_n, rows, u),
                       Mat(b.d_h, rows, u));
    lstm_.backward(params, grads, CMat(b.dense_n, rows, h), sequences, steps, b.reset, b.lstm,
                   CMat(b.d_h, rows, u), Mat(b.d_dense_n, rows, h), lstm_packed);
  } else {
    out_norm_.backward(params, grads, CMat(b.dense_n, rows, u), b.out_stats, CMat(b.d_out_n, rows, u),
                       Mat(b.d_dense_n, rows, h));
  }
  const Mat dz(b.d_dense_n, rows, h);
  dense_norm_.backward_fused(params, grads, CMat(b.dense_a, rows, h), b.dense_stats, Activation::kRelu, dz,
                             dz, nullptr);
  dense_.backward_preact(params, grads, CMat(b.cat_n, rows, 2 * d), dz, Mat(b.d_cat_n, rows, 2 * d), false);
  cat_norm_.backward(params, grads, CMat(b.cat, rows, 2 * d), b.cat_stats, CMat(b.d_cat_n, rows, 2 * d),
                     Mat(b.d_cat, rows, 2 * d));

  // Pool, attention; the self embedding also feeds the concat directly.
  masked_mean_pool_backward(CMat(b.d_cat + d, rows, d, 2 * d), b.mask, e, Mat(b.d_sa_out, rows * e, d));
  attention_.backward(params, grads, CMat(b.x, rows * e, d), b.mask, e, b.sa, CMat(b.sa_out, rows * e, d),
                      CMat(b.d_sa_out, rows * e, d), Mat(b.d_x, rows * e, d));
  const EntitySlots self_slot{b.x, rows, e, d, e - 1, 1};
  const EntitySlots d_self_slot{b.d_x, rows, e, d, e - 1, 1};
  for (int r = 0; r < rows; ++r) {
    float* dst = d_self_slot.at(r, 0);
    const float* src = b.d_cat + static_cast<ptrdiff_t>(r) * 2 * d;
    for (int i = 0; i < d; ++i) dst[i] += src[i];
  }

  // Embeddings (gradient w.r.t. main accumulated), then the lidar conv's share of main. Their weight
  // gradients' x_self parts all multiply main: in bf16 its transpose is converted once for them.
  const SharedRows main = convert_shared_t(params, CMat(b.main, rows, m));
  const Mat d_main(b.d_main, rows, m);
  self_embed_.backward(params, grads, main, self_slot.slot(0), d_self_slot.slot(0), d_main, false);
  const Mat scratch_rows(b.embed_rows, rows, d);
  if (na > 0)
    agents_embed_.backward(params, grads, main, CMat(b.agents_n, rows * na, o.agent_features),
                           {b.x, rows, e, d, 0, na}, {b.d_x, rows, e, d, 0, na}, scratch_rows,
                           Mat(b.embed_ent, rows * na, d), d_main);
  if (nb > 0)
    boxes_embed_.backward(params, grads, main, CMat(b.boxes_n, rows * nb, o.box_features),
                          {b.x, rows, e, d, na, nb}, {b.d_x, rows, e, d, na, nb}, scratch_rows,
                          Mat(b.embed_ent, rows * nb, d), d_main);
  if (nr > 0)
    ramps_embed_.backward(params, grads, main, CMat(b.ramps_n, rows * nr, o.ramp_features),
                          {b.x, rows, e, d, na + nb, nr}, {b.d_x, rows, e, d, na + nb, nr}, scratch_rows,
                          Mat(b.embed_ent, rows * nr, d), d_main);
  if (nc > 0)
    sites_embed_.backward(params, grads, main, CMat(b.sites_n, rows * nc, o.site_features),
                          {b.x, rows, e, d, na + nb + nr, nc}, {b.d_x, rows, e, d, na + nb + nr, nc},
                          scratch_rows, Mat(b.embed_ent, rows * nc, d), d_main);
  conv_.backward(params, grads, CMat(b.lidar_n, rows, l), CMat(b.main + s, rows, conv_.out_width(), m),
                 Mat(b.d_main + s, rows, conv_.out_width(), m));
}

}  // namespace hns::nn
