#include "ppo/rnd.hpp"

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/parallel_for.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>

namespace hns::ppo {

namespace {

nn::NetConfig rnd_config(nn::NetConfig c) {
  c.lstm = 0;
  return c;
}

nn::ParamLayout net_layout(const nn::NetConfig& cfg, const char* prefix, nn::EntityNet& net) {
  nn::ParamLayout layout;
  net = nn::EntityNet(cfg, nn::NetHead::kRnd, layout, prefix);
  return layout;
}

constexpr uint64_t kTargetStream = 0x52ADC0DE0001ULL, kPredictorStream = 0x52ADC0DE0002ULL;

}  // namespace

struct Rnd::Work {
  nn::EntityNet::Work target, predictor;
  nn::FloatBuffer target_out;  // [kRndChunkRows, 64]
  nn::FloatBuffer d_out;       // [kRndChunkRows, 64]
};

Rnd::Rnd(const nn::NetConfig& base, uint64_t seed, float lr)
    : cfg_(rnd_config(base)),
      target_(net_layout(cfg_, "rnd_target", target_net_)),
      predictor_(net_layout(cfg_, "rnd_predictor", predictor_net_)) {
  target_.init(seed ^ kTargetStream);
  predictor_.init(seed ^ kPredictorStream);
  nn::AdamConfig ac;
  ac.lr = lr;
  adam_ = std::make_unique<nn::Adam>(predictor_.layout(), ac);
  group_grads_.resize(kRndGroups);
  for (nn::FloatBuffer& g : group_grads_) g.resize(predictor_.buffer_floats());
}

Rnd::~Rnd() = default;

size_t Rnd::predictor_floats(const nn::NetConfig& base) {
  nn::EntityNet net;
  return net_layout(rnd_config(base), "rnd_predictor", net).buffer_floats();
}

Rnd::Work& Rnd::local_work() const {
  std::unique_ptr<Work>& w = work_.local();
  if (!w) {
    w = std::make_unique<Work>();
    w->target = target_net_.make_workspace(kRndChunkRows, 1);
    w->predictor = predictor_net_.make_workspace(kRndChunkRows, 1);
    w->target_out.resize(size_t(kRndChunkRows) * nn::kRndOutputs);
    w->d_out.resize(size_t(kRndChunkRows) * nn::kRndOutputs);
  }
  return *w;
}

void Rnd::forward_both(const nn::ObsNormView& norm, const nn::ObsBatch& obs, int rows, Work& w) const {
  const nn::NetInputs in = obs.value_inputs();
  target_net_.forward(target_.values(), norm, in, rows, 1, nullptr, nullptr, w.target);
  std::memcpy(w.target_out.data(), target_net_.output(w.target, rows).data,
              sizeof(float) * size_t(rows) * nn::kRndOutputs);
  predictor_net_.forward(predictor_.values(), norm, in, rows, 1, nullptr, nullptr, w.predictor);
}

void Rnd::errors(const nn::ObsNormView& norm, const nn::ObsBatch& obs, size_t rows, float* out) const {
  if (obs.index != nullptr) throw std::invalid_argument("Rnd::errors: contiguous rows only");
  const int chunks = int((rows + kRndChunkRows - 1) / kRndChunkRows);
  tbb::parallel_for(tbb::blocked_range<int>(0, chunks, 1), [&](const tbb::blocked_range<int>& range) {
    Work& w = local_work();
    for (int c = range.begin(); c < range.end(); ++c) {
      const size_t first = size_t(c) * kRndChunkRows;
      const int n = int(std::min<size_t>(kRndChunkRows, rows - first));
      forward_both(norm, obs.rows_from(first, cfg_.obs), n, w);
      const float* p = predictor_net_.output(w.predictor, n).data;
      for (int r = 0; r < n; ++r) {
        float sum = 0.0f;
        for (int k = 0; k < nn::kRndOutputs; ++k) {
          const float d = p[r * nn::kRndOutputs + k] - w.target_out[size_t(r) * nn::kRndOutputs + k];
          sum += d * d;
        }
        out[first + size_t(r)] = sum / float(nn::kRndOutputs);
      }
    }
  });
}

double Rnd::train(const nn::ObsNormView& norm, const nn::ObsBatch& obs, std::span<const int32_t> rows) {
  if (obs.index != nullptr) throw std::invalid_argument("Rnd::train: obs.index must be null");
  if (rows.empty()) return 0.0;
  const int chunks = int((rows.size() + kRndChunkRows - 1) / kRndChunkRows);
  const int groups = std::min(kRndGroups, chunks);
  std::vector<double> chunk_loss(size_t(chunks), 0.0);
  // d loss / d output for loss = mean over rows and outputs of the squared difference.
  const float scale = 2.0f / (float(rows.size()) * float(nn::kRndOutputs));
  tbb::parallel_for(tbb::blocked_range<int>(0, groups, 1), [&](const tbb::blocked_range<int>& range) {
    Work& w = local_work();
    for (int g = range.begin(); g < range.end(); ++g) {
      float* grads = group_grads_[size_t(g)].data();
      std::fill_n(grads, predictor_.buffer_floats(), 0.0f);
      const int c0 = int(int64_t(g) * chunks / groups), c1 = int(int64_t(g + 1) * chunks / groups);
      for (int c = c0; c < c1; ++c) {
        const size_t first = size_t(c) * kRndChunkRows;
        const int n = int(std::min<size_t>(kRndChunkRows, rows.size() - first));
        nn::ObsBatch sub = obs;
        sub.index = rows.data() + first;
        forward_both(norm, sub, n, w);
        const float* p = predictor_net_.output(w.predictor, n).data;
        double loss = 0.0;
        for (size_t i = 0; i < size_t(n) * nn::kRndOutputs; ++i) {
          const float d = p[i] - w.target_out[i];
          loss += double(d) * d;
          w.d_out[i] = scale * d;
        }
        chunk_loss[size_t(c)] = loss;
        predictor_net_.backward(predictor_.values(), grads, n, 1,
                                nn::CMat(w.d_out.data(), n, nn::kRndOutputs), w.predictor);
      }
    }
  });
  float* total = predictor_.grads();
  std::copy_n(group_grads_[0].data(), predictor_.buffer_floats(), total);
  for (int g = 1; g < groups; ++g) {
    const float* src = group_grads_[size_t(g)].data();
    for (size_t i = 0; i < predictor_.buffer_floats(); ++i) total[i] += src[i];
  }
  double loss = 0.0;
  for (double l : chunk_loss) loss += l;
  adam_->step(predictor_.values(), total);
  return loss / (double(rows.size()) * nn::kRndOutputs);
}

}  // namespace hns::ppo
