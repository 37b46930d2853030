#include "nn/actor_critic.hpp"

#include "nn/simd.hpp"

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/parallel_invoke.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <cstring>

namespace hns::nn {
namespace {

const float* offset(const float* p, size_t first, size_t per_row) {
  return p == nullptr ? nullptr : p + first * per_row;
}

// policy() and value() as two tasks (the caller isolates them: compute_groups).
template <class Policy, class Value>
void both_nets(const Policy& policy, const Value& value) {
  tbb::parallel_invoke(policy, value);
}

// The layout of both networks: policy slices first, then value slices.
ParamLayout build_layout(const NetConfig& cfg, EntityNet& policy, EntityNet& value) {
  ParamLayout layout;
  policy = EntityNet(cfg, NetHead::kPolicy, layout, "policy");
  value = EntityNet(cfg, NetHead::kValue, layout, "value");
  return layout;
}

}  // namespace

ParamLayout ActorCritic::layout_of(const NetConfig& cfg) {
  EntityNet policy, value;
  return build_layout(cfg, policy, value);
}

ObsBatch ObsBatch::rows_from(size_t first, const ObsShape& s) const {
  if (index != nullptr) {
    ObsBatch b = *this;
    b.index = index + first;
    return b;
  }
  const size_t na = s.num_other_agents();
  ObsBatch b;
  b.self = offset(self, first, s.self_features);
  b.lidar = offset(lidar, first, s.lidar_rays);
  b.agents = offset(agents, first, na * s.agent_features);
  b.boxes = offset(boxes, first, static_cast<size_t>(s.max_boxes) * s.box_features);
  b.ramps = offset(ramps, first, static_cast<size_t>(s.max_ramps) * s.ramp_features);
  b.sites = offset(sites, first, static_cast<size_t>(s.max_sites) * s.site_features);
  b.agents_seen = offset(agents_seen, first, na);
  b.boxes_seen = offset(boxes_seen, first, s.max_boxes);
  b.ramps_seen = offset(ramps_seen, first, s.max_ramps);
  b.sites_seen = offset(sites_seen, first, s.max_sites);
  b.agents_present = offset(agents_present, first, na);
  b.boxes_present = offset(boxes_present, first, s.max_boxes);
  b.ramps_present = offset(ramps_present, first, s.max_ramps);
  b.sites_present = offset(sites_present, first, s.max_sites);
  b.reset = offset(reset, first, 1);
  return b;
}

NetInputs ObsBatch::policy_inputs() const {
  return {self,        lidar,      agents,     boxes,      ramps, sites,
          agents_seen, boxes_seen, ramps_seen, sites_seen, reset, index};
}

NetInputs ObsBatch::value_inputs() const {
  return {self,           lidar,         agents,        boxes,         ramps, sites,
          agents_present, boxes_present, ramps_present, sites_present, reset, index};
}

// Per-thread activations for one chunk shape, and the chunk's output-gradient scratch.
struct ActorCritic::ThreadWork {
  int sequences;
  int steps;
  EntityNet::Work policy;
  EntityNet::Work value;
  FloatBuffer d_logits;        // [rows, num_logits]
  FloatBuffer d_value;         // [rows]
  std::vector<int32_t> index;  // [sequences] an inference chunk's rows, padded
  FloatBuffer state_p;         // [sequences, state width] its LSTM states, padded
  FloatBuffer state_v;
  // Each network's weight gradients over several chunks (training, bf16), a line apart: the two networks'
  // tasks update them at once.
  alignas(64) GradStage stage_p;
  alignas(64) GradStage stage_v;
  ThreadWork(const ActorCritic& ac, int seqs, int st)
      : sequences(seqs),
        steps(st),
        policy(ac.policy_.make_workspace(seqs, st)),
        value(ac.value_.make_workspace(seqs, st)),
        d_logits(static_cast<size_t>(seqs) * st * ac.heads_.num_logits()),
        d_value(static_cast<size_t>(seqs) * st),
        index(static_cast<size_t>(seqs)),
        state_p(static_cast<size_t>(seqs) * ac.state_width()),
        state_v(static_cast<size_t>(seqs) * ac.state_width()) {}
};

ActorCritic::ActorCritic(const NetConfig& cfg, ParallelConfig parallel)
    : cfg_(cfg),
      par_(parallel),
      heads_(cfg.action_heads),
      params_(build_layout(cfg, policy_, value_)),
      train_pool_(std::make_unique<WorkPool>()) {
  HNS_NN_CHECK(
      par_.infer_chunk_agents > 0 && par_.train_chunk_sequences >= 0 && par_.grad_groups > 0,
      "parallel chunk sizes must be positive (a training chunk of 0 sequences: the network's default)");
  if (par_.train_chunk_sequences == 0) par_.train_chunk_sequences = default_train_chunk(cfg);
}

int default_train_chunk(const NetConfig& cfg) {
  return cfg.embed <= 64 ? 4 : 16;
}

ActorCritic::~ActorCritic() = default;

ActorCritic::ThreadWork& ActorCritic::local_work(
    tbb::enumerable_thread_specific<std::unique_ptr<ThreadWork>>& ets, int sequences, int steps) const {
  std::unique_ptr<ThreadWork>& w = ets.local();
  if (!w || w->sequences != sequences || w->steps != steps)
    w = std::make_unique<ThreadWork>(*this, sequences, steps);
  return *w;
}

std::unique_ptr<ActorCritic::ThreadWork> ActorCritic::take_train_work(int sequences, int steps) {
  std::unique_ptr<ThreadWork> w;
  {
    const std::lock_guard<std::mutex> lock(train_pool_->mutex);
    if (!train_pool_->idle.empty()) {
      w = std::move(train_pool_->idle.back());
      train_pool_->idle.pop_back();
    }
  }
  if (!w || w->sequences != sequences || w->steps != steps)
    w = std::make_unique<ThreadWork>(*this, sequences, steps);
  return w;
}

void ActorCritic::give_back(std::unique_ptr<ThreadWork> w) {
  const std::lock_guard<std::mutex> lock(train_pool_->mutex);
  train_pool_->idle.push_back(std::move(w));
}

void ActorCritic::pack_lstms(bool for_backward) const {
  const EntityNet* nets[2] = {&policy_, &value_};
  for (int i = 0; i < 2; ++i) {
    const size_t n = nets[i]->lstm_packed_floats();
    if (lstm_packed_buf_[i].size() != 2 * n) {
      lstm_packed_buf_[i].resize(2 * n);
      lstm_packed_[i] = {lstm_packed_buf_[i].data(), lstm_packed_buf_[i].data() + n};
    }
    nets[i]->pack_lstm(params_.values(), for_backward, lstm_packed_[i]);
  }
}

void ActorCritic::set_precision(Precision p) {
  if (p == Precision::kBf16) {
    resolve_precision("bf16");  // throws, with the reason, where this CPU has no bf16 dot product
    if (!packed_) packed_ = std::make_unique<PackedWeights>(params_.layout());
  }
  precision_ = p;
  packed_stale_ = true;
}

Weights ActorCritic::prepare_weights(bool for_backward) const {
  const float* values = params_.values();
  if (precision_ == Precision::kFp32) {
    pack_lstms(for_backward);
    return Weights(values);
  }
  if (for_backward || packed_stale_ || packed_->kernel() != bf16::kernel()) {
    packed_->pack(values, for_backward);
    packed_stale_ = false;
  }
  return Weights(values, packed_.get());
}

void ActorCritic::act(const ObsNormView& norm, const ObsBatch& obs, int agents, float* policy_state,
                      float* value_state, const float* uniforms, const ActOutputs& out) const {
  const int chunk = par_.infer_chunk_agents;
  const int num_chunks = (agents + chunk - 1) / chunk;
  const int sw = state_width();
  const int nh = heads_.num_heads();
  const int nl = heads_.num_logits();
  const Weights p = prepare_weights(false);
  auto padded = [](int rows) { return (rows + kActRowAlign - 1) / kActRowAlign * kActRowAlign; };
  tbb::parallel_for(0, num_chunks, [&](int c) {
    ThreadWork& w = local_work(infer_work_, padded(chunk), 1);
    const int first = c * chunk;
    const int n = std::min(chunk, agents - first);
    // The chunk padded with copies of its first row (results unused), so that every product has a whole
    // number of row panels and a row's outputs do not depend on how many rows its chunk has (a run split
    // over processes cuts its chunks elsewhere).
    const int n_pad = padded(n);
    ObsBatch sub = obs.rows_from(first, cfg_.obs);
    for (int i = 0; i < n_pad; ++i) {
      const int r = i < n ? i : 0;
      w.index[size_t(i)] = sub.index != nullptr ? sub.index[r] : r;
    }
    sub.index = w.index.data();
    float* ps = policy_state + static_cast<ptrdiff_t>(first) * sw;
    float* vs = value_state + static_cast<ptrdiff_t>(first) * sw;
    const size_t real = static_cast<size_t>(n) * sw, all = static_cast<size_t>(n_pad) * sw;
    std::copy_n(ps, real, w.state_p.data());
    std::copy_n(vs, real, w.state_v.data());
    std::fill(w.state_p.data() + real, w.state_p.data() + all, 0.0f);
    std::fill(w.state_v.data() + real, w.state_v.data() + all, 0.0f);
    policy_.forward(p, norm, sub.policy_inputs(), n_pad, 1, w.state_p.data(), w.state_p.data(), w.policy,
                    &lstm_packed_[0]);
    value_.forward(p, norm, sub.value_inputs(), n_pad, 1, w.state_v.data(), w.state_v.data(), w.value,
                   &lstm_packed_[1]);
    std::copy_n(w.state_p.data(), real, ps);
    std::copy_n(w.state_v.data(), real, vs);
    const CMat logits = policy_.output(w.policy, n);
    heads_.sample(logits, uniforms + static_cast<ptrdiff_t>(first) * nh,
                  out.actions + static_cast<ptrdiff_t>(first) * nh,
                  out.logp == nullptr ? nullptr : out.logp + first);
    const CMat v = value_.output(w.value, n);
    if (out.value != nullptr)
      for (int i = 0; i < n; ++i) out.value[first + i] = v.at(i, 0);
    if (out.logits != nullptr)
      for (int i = 0; i < n; ++i)
        std::memcpy(out.logits + static_cast<ptrdiff_t>(first + i) * nl, logits.row(i), sizeof(float) * nl);
  });
}

void ActorCritic::forward_backward(const ObsNormView& norm, const ObsBatch& obs, int sequences, int steps,
                                   const float* policy_state0, const float* value_state0, const LossFn& loss,
                                   std::span<double> stats, float* grads_out,
                                   std::span<const int> group_sequences) {
  compute_groups(norm, obs, sequences, steps, policy_state0, value_state0, loss, stats.size(),
                 group_sequences);
  // Each element independently, so any split of the index range gives the same bits.
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, params_.buffer_floats(), 1 << 14),
      [&](const tbb::blocked_range<size_t>& r) { sum_groups(r.begin(), r.end(), nullptr, grads_out); });
  const size_t nstats = stats.size();
  for (size_t k = 0; k < nstats; ++k) stats[k] = 0.0;
  if (nstats == 0) return;
  for (size_t c = 0; c < chunk_stats_.size() / nstats; ++c)
    for (size_t k = 0; k < nstats; ++k) stats[k] += chunk_stats_[c * nstats + k];
}

void ActorCritic::sum_groups(size_t begin, size_t end, const float* before, float* out) {
  const int groups = summed_groups_;
  // Each element in group order (before, group 0, group 1, ...), so any split of the range gives the same
  // bits; vectors of elements at a time. Each group's vector is zeroed as it is read (its line is in the
  // cache now; a separate clearing pass would fetch it again).
  float* first = group_grads_[0].data() + begin;
  float* dst = out + begin;
  simd::for_each<true>(static_cast<int>(end - begin), [&](auto tag, int i) {
    using F = decltype(tag);
    F s = simd::load<F>(first + i);
    simd::store(first + i, F(0.0f));
    if (before != nullptr) s = simd::load<F>(before + i) + s;
    for (int g = 1; g < groups; ++g) {
      float* gi = group_grads_[g].data() + begin + i;
      s = s + simd::load<F>(gi);
      simd::store(gi, F(0.0f));
    }
    simd::store(dst + i, s);
  });
  zeroed_floats_->fetch_add(end - begin, std::memory_order_acq_rel);
}

void ActorCritic::compute_groups(const ObsNormView& norm, const ObsBatch& obs, int sequences, int steps,
                                 const float* policy_state0, const float* value_state0, const LossFn& loss,
                                 size_t nstats, std::span<const int> group_sequences) {
  const int chunk = par_.train_chunk_sequences;
  // The chunks, group by group.
  chunks_.clear();
  group_chunks_.assign(1, 0);
  if (group_sequences.empty()) {
    for (int s = 0; s < sequences; s += chunk) chunks_.push_back({s, std::min(chunk, sequences - s)});
    const int n = static_cast<int>(chunks_.size());
    const int groups = std::max(1, std::min(par_.grad_groups, n));
    for (int g = 1; g <= groups; ++g) group_chunks_.push_back(static_cast<int>(int64_t(n) * g / groups));
  } else {
    HNS_NN_CHECK(
        group_sequences.size() >= 2 && group_sequences.front() == 0 && group_sequences.back() == sequences,
        "group_sequences must run from 0 to the sequence count");
    for (size_t g = 0; g + 1 < group_sequences.size(); ++g) {
      HNS_NN_CHECK(group_sequences[g] <= group_sequences[g + 1], "group_sequences must not decrease");
      for (int s = group_sequences[g]; s < group_sequences[g + 1]; s += chunk)
        chunks_.push_back({s, std::min(chunk, group_sequences[g + 1] - s)});
      group_chunks_.push_back(static_cast<int>(chunks_.size()));
    }
  }
  const int num_chunks = static_cast<int>(chunks_.size());
  const int groups = static_cast<int>(group_chunks_.size()) - 1;
  const size_t nfloats = params_.buffer_floats();
  const int sw = state_width();
  const int nl = heads_.num_logits();
  while (group_grads_.size() < static_cast<size_t>(groups)) {
    group_grads_.emplace_back(nfloats);  // zeroed
    group_dirty_.push_back(0);
  }
  // The groups the last sum read are clear if it read every float (sum_groups zeroes what it reads).
  if (zeroed_floats_->exchange(0) == nfloats) std::fill_n(group_dirty_.begin(), summed_groups_, uint8_t{0});
  group_clear_.assign(group_dirty_.begin(), group_dirty_.begin() + groups);
  std::fill_n(group_dirty_.begin(), groups, uint8_t{1});
  summed_groups_ = groups;
  chunk_stats_.assign(static_cast<size_t>(num_chunks) * nstats, 0.0);
  const Weights p = prepare_weights(true);

  // Each group: its chunks in order, gradients summed into its own buffer.
  auto group = [&](int g) {
    std::unique_ptr<ThreadWork> work = take_train_work(chunk, steps);
    ThreadWork& w = *work;
    float* gg = group_grads_[g].data();
    if (group_clear_[g] != 0) group_grads_[g].fill_zero();
    w.stage_p.clear();
    w.stage_v.clear();
    Weights pw = p, vw = p;
    if (p.bf16() && par_.stage_weight_grads) {
      pw.stage = &w.stage_p;
      vw.stage = &w.stage_v;
    }
    for (int c = group_chunks_[g]; c < group_chunks_[g + 1]; ++c) {
      const bool last = c + 1 == group_chunks_[g + 1];
      const int first_seq = chunks_[c].first_seq;
      const int n = chunks_[c].sequences;
      const int first_row = first_seq * steps;
      const int rows = n * steps;
      const ObsBatch sub = obs.rows_from(first_row, cfg_.obs);
      const NetInputs pin = sub.policy_inputs();
      const NetInputs vin = sub.value_inputs();
      // The two networks are independent up to the loss and after it (each writes its own parameters'
      // slice of gg), so each pass is two tasks: a thread with no group left may take one of them.
      both_nets(
          [&] {
            policy_.forward(
                p, norm, pin, n, steps,
                policy_state0 == nullptr ? nullptr : policy_state0 + static_cast<ptrdiff_t>(first_seq) * sw,
                nullptr, w.policy, &lstm_packed_[0]);
          },
          [&] {
            value_.forward(
                p, norm, vin, n, steps,
                value_state0 == nullptr ? nullptr : value_state0 + static_cast<ptrdiff_t>(first_seq) * sw,
                nullptr, w.value, &lstm_packed_[1]);
          });
      const ChunkOutputs outs{first_row, rows, policy_.output(w.policy, rows), w.value.bufs().head};
      const ChunkGrads grads{Mat(w.d_logits.data(), rows, nl), w.d_value.data()};
      loss(outs, grads, std::span<double>(chunk_stats_.data() + static_cast<size_t>(c) * nstats, nstats));
      // (A network's staged weight gradients go into gg at its group's last chunk, in its own task.)
      both_nets(
          [&] {
            policy_.backward(pw, gg, n, steps, CMat(w.d_logits.data(), rows, nl), w.policy, &lstm_packed_[0]);
            if (last) w.stage_p.flush();
          },
          [&] {
            value_.backward(vw, gg, n, steps, CMat(w.d_value.data(), rows, 1), w.value, &lstm_packed_[1]);
            if (last) w.stage_v.flush();
          });
    }
    give_back(std::move(work));
  };
  // Isolated: while a group waits for one of its networks, its thread runs nothing but the group's own tasks
  // (another group started there would hold this one up until it ended, and groups would nest on one
  // thread's stack). Threads with no group left still take a network of a group that is running.
  tbb::parallel_for(0, groups, [&](int g) { tbb::this_task_arena::isolate([&] { group(g); }); });
}

}  // namespace hns::nn
