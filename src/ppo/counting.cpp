#include "ppo/counting.hpp"

#include "batch/host.hpp"
#include "batch/scenes.hpp"
#include "nn/adam.hpp"
#include "nn/layers.hpp"
#include "physics/rng.hpp"
#include "ppo/policy.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace hns::ppo {

void collect_counting_states(const Trainer& trainer, int64_t first_episode, int episodes, int envs,
                             int threads, std::vector<float>& states, std::vector<int32_t>& labels) {
  const TrainConfig& tc = trainer.config();
  const batch::SceneInfo* scene = batch::find_scene(tc.scene);
  if (scene == nullptr || scene->family != batch::SceneFamily::kProbe)
    throw std::invalid_argument("collect_counting_states: the trainer's scene is " + tc.scene +
                                ", not object-counting");
  batch::BatchConfig bc = tc.batch_config();
  bc.num_envs = envs;
  bc.threads = batch::usable_threads(threads);
  bc.seed = tc.seed;
  batch::BatchSim sim(bc);
  Policy policy(trainer, tc.seed);
  const int A = sim.layout().max_agents, sw = policy.state_width(), units = sw / 2;
  const int horizon = bc.world.horizon;
  std::vector<float> ps(size_t(envs) * A * sw), vs(ps.size());
  std::vector<physics::AgentAction> actions(size_t(envs) * A);
  std::vector<int32_t> numbers(static_cast<size_t>(envs));
  states.assign(size_t(episodes) * units, 0.0f);
  labels.assign(size_t(episodes), 0);
  for (int done = 0; done < episodes; done += envs) {
    for (int e = 0; e < envs; ++e) numbers[size_t(e)] = int32_t(first_episode + done + e);
    sim.reset(numbers);
    for (int t = 0; t < horizon; ++t) {
      policy.act(StepObsView::of(sim.state()), envs, ps.data(), vs.data(), actions);
      if (t + 1 < horizon) {
        sim.step(actions);
        continue;
      }
      // The last observation has been read: the state now holds the whole episode.
      for (int e = 0; e < envs && done + e < episodes; ++e) {
        const float* h = ps.data() + size_t(e) * A * sw + units;  // agent 0's (c, h): h
        std::copy_n(h, units, states.data() + size_t(done + e) * units);
        const std::vector<int8_t>& sides = sim.world(e).scene().sides;
        labels[size_t(done + e)] = int32_t(std::count(sides.begin(), sides.end(), int8_t{-1}));
      }
    }
  }
}

namespace {

// The head: layer norm, dense hidden + ReLU, dense 7 (logits).
struct Head {
  nn::LayerNorm norm;
  nn::Dense hidden, out;
  nn::ParamStore params;
  Head(int units, int width) : params(build(units, width)) {}
  nn::ParamLayout build(int units, int width) {
    nn::ParamLayout layout;
    norm = nn::LayerNorm(layout, "counting/norm", units);
    hidden = nn::Dense(layout, "counting/hidden", units, width, nn::Activation::kRelu);
    out = nn::Dense(layout, "counting/logits", width, kCountingClasses, nn::Activation::kNone);
    return layout;
  }
};

// Scratch for `rows` rows.
struct Pass {
  std::vector<float> x, xn, stats, a, logits, dlogits, da, dxn, dx;
  Pass(int rows, int units, int width)
      : x(size_t(rows) * units),
        xn(x.size()),
        stats(size_t(rows) * 2),
        a(size_t(rows) * width),
        logits(size_t(rows) * kCountingClasses),
        dlogits(logits.size()),
        da(a.size()),
        dxn(x.size()),
        dx(x.size()) {}
};

void forward(const Head& h, int rows, int units, int width, Pass& p) {
  const float* w = h.params.values();
  h.norm.forward(w, nn::CMat(p.x.data(), rows, units), nn::Mat(p.xn.data(), rows, units), p.stats.data());
  h.hidden.forward(w, nn::CMat(p.xn.data(), rows, units), nn::Mat(p.a.data(), rows, width));
  h.out.forward(w, nn::CMat(p.a.data(), rows, width), nn::Mat(p.logits.data(), rows, kCountingClasses));
}

int argmax(const float* logits) {
  return int(std::max_element(logits, logits + kCountingClasses) - logits);
}

double accuracy(const Head& h, int units, int width, const std::vector<float>& states,
                const std::vector<int32_t>& labels) {
  const int n = int(labels.size());
  if (n == 0) return 0.0;
  Pass p(n, units, width);
  std::copy(states.begin(), states.end(), p.x.begin());
  forward(h, n, units, width, p);
  int right = 0;
  for (int r = 0; r < n; ++r) right += argmax(&p.logits[size_t(r) * kCountingClasses]) == labels[size_t(r)];
  return double(right) / n;
}

}  // namespace

CountingHeadResult train_counting_head(int units, const std::vector<float>& train_states,
                                       const std::vector<int32_t>& train_labels,
                                       const std::vector<float>& test_states,
                                       const std::vector<int32_t>& test_labels,
                                       const CountingHeadConfig& cfg) {
  const int n = int(train_labels.size()), width = cfg.hidden;
  if (n == 0 || train_states.size() != size_t(n) * units || test_states.size() != test_labels.size() * units)
    throw std::invalid_argument("train_counting_head: states and labels do not match");
  Head head(units, width);
  head.params.init(cfg.seed);
  nn::AdamConfig ac;
  ac.lr = float(cfg.lr);
  nn::Adam adam(head.params.layout(), ac);
  physics::Rng rng(cfg.seed, 0xC0C0, 0);
  std::vector<int> order(static_cast<size_t>(n));
  std::iota(order.begin(), order.end(), 0);
  const int b = std::min(cfg.batch, n);
  Pass p(b, units, width);
  CountingHeadResult result;
  for (int epoch = 0; epoch < cfg.epochs; ++epoch) {
    for (int i = n - 1; i > 0; --i) std::swap(order[size_t(i)], order[size_t(rng.uniform_int(0, i + 1))]);
    double loss_sum = 0;
    for (int first = 0; first < n; first += b) {
      const int rows = std::min(b, n - first);
      for (int r = 0; r < rows; ++r) {
        const int i = order[size_t(first + r)];
        std::copy_n(train_states.data() + size_t(i) * units, units, p.x.data() + size_t(r) * units);
      }
      forward(head, rows, units, width, p);
      // Softmax cross-entropy, averaged over the batch's rows.
      for (int r = 0; r < rows; ++r) {
        const float* z = &p.logits[size_t(r) * kCountingClasses];
        float* dz = &p.dlogits[size_t(r) * kCountingClasses];
        const float top = *std::max_element(z, z + kCountingClasses);
        double sum = 0;
        for (int k = 0; k < kCountingClasses; ++k) sum += std::exp(double(z[k] - top));
        const int label = train_labels[size_t(order[size_t(first + r)])];
        loss_sum += std::log(sum) - double(z[label] - top);
        for (int k = 0; k < kCountingClasses; ++k)
          dz[k] = float((std::exp(double(z[k] - top)) / sum - (k == label ? 1.0 : 0.0)) / rows);
      }
      head.params.zero_grads();
      const float* w = head.params.values();
      float* g = head.params.grads();
      head.out.backward(
          w, g, nn::CMat(p.a.data(), rows, width), nn::CMat(p.logits.data(), rows, kCountingClasses),
          nn::Mat(p.dlogits.data(), rows, kCountingClasses), nn::Mat(p.da.data(), rows, width), false);
      head.hidden.backward(w, g, nn::CMat(p.xn.data(), rows, units), nn::CMat(p.a.data(), rows, width),
                           nn::Mat(p.da.data(), rows, width), nn::Mat(p.dxn.data(), rows, units), false);
      head.norm.backward(w, g, nn::CMat(p.x.data(), rows, units), p.stats.data(),
                         nn::CMat(p.dxn.data(), rows, units), nn::Mat(p.dx.data(), rows, units));
      adam.step(head.params.values(), g);
    }
    result.train_loss = loss_sum / n;
  }
  result.train_accuracy = accuracy(head, units, width, train_states, train_labels);
  result.test_accuracy = accuracy(head, units, width, test_states, test_labels);
  std::vector<int> count(kCountingClasses, 0);
  for (int32_t l : train_labels) ++count[size_t(l)];
  const int majority = int(std::max_element(count.begin(), count.end()) - count.begin());
  int hits = 0;
  for (int32_t l : test_labels) hits += l == majority;
  result.majority_accuracy = test_labels.empty() ? 0.0 : double(hits) / double(test_labels.size());
  return result;
}

}  // namespace hns::ppo
