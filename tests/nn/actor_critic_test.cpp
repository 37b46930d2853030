// The policy and value networks (EntityNet, ActorCritic): parameter counts of the presets, end-to-end
// gradients, masking, LSTM stepping, determinism across thread counts, and a short training run that learns.
#include "nn/actor_critic.hpp"
#include "nn/adam.hpp"
#include "nn/bf16_gemm.hpp"
#include "nn/kernels.hpp"
#include "nn/obs_store.hpp"

#include "net_data.hpp"
#include "test_util.hpp"

#include <gtest/gtest.h>
#include <oneapi/tbb/global_control.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

namespace hns::nn {
namespace {

using testing::fitted_normalizer;
using testing::ObsData;
using testing::outputs_and_grads;
using testing::random_mask;
using testing::random_vector;
using testing::Result;

NetConfig tiny_config() {
  return testing::tiny_net_config();
}

// The tests below run for both precisions of the products, bf16 on each of its kernels this CPU runs
// (vdpbf16ps, AMX tiles, and the AMX kernel's emulation, which checks the AMX layouts anywhere).
struct ProductPath {
  Precision precision;
  bf16::Kernel kernel;
  const char* name;
};
void PrintTo(const ProductPath& p, std::ostream* os) {
  *os << p.name;
}
class NnNetworkPrecision : public ::testing::TestWithParam<ProductPath> {
 protected:
  void SetUp() override {
    if (precision() == Precision::kFp32) return;
    if (!bf16::available()) GTEST_SKIP() << "this CPU has no AVX512-BF16: bf16 products cannot run here";
    if (GetParam().kernel == bf16::Kernel::kAmx && !bf16::amx_available())
      GTEST_SKIP() << "this CPU has no AMX-BF16 tiles";
    saved_ = bf16::kernel();
    bf16::set_kernel(GetParam().kernel);
    switched_ = true;
  }
  void TearDown() override {
    if (switched_) bf16::set_kernel(saved_);
  }
  Precision precision() const { return GetParam().precision; }
  void use(ActorCritic& ac) const { ac.set_precision(precision()); }

 private:
  bf16::Kernel saved_ = bf16::Kernel::kAvx512Bf16;
  bool switched_ = false;
};
INSTANTIATE_TEST_SUITE_P(Precisions, NnNetworkPrecision,
                         ::testing::Values(ProductPath{Precision::kFp32, bf16::Kernel::kAvx512Bf16, "fp32"},
                                           ProductPath{Precision::kBf16, bf16::Kernel::kAvx512Bf16, "bf16"},
                                           ProductPath{Precision::kBf16, bf16::Kernel::kAmx, "bf16_amx"},
                                           ProductPath{Precision::kBf16, bf16::Kernel::kAmxEmulated,
                                                       "bf16_amx_emulated"}),
                         [](const ::testing::TestParamInfo<ProductPath>& info) { return info.param.name; });

bool same_bits(const float* a, const float* b, size_t n) {
  return std::memcmp(a, b, n * sizeof(float)) == 0;
}

TEST(NnNetwork, PaperPresetHasAboutOnePointSixMillionParameters) {
  ActorCritic ac(net_preset("paper"));
  // docs/game.md §10.3: about 1.63 M (policy about 818 k of which the LSTM is 525 k, value about 809 k); ours
  // has 11 self and agent features (yaw as cos/sin) instead of 10.
  EXPECT_NEAR(static_cast<double>(ac.num_params()), 1.63e6, 0.02 * 1.63e6);
  EXPECT_EQ(ac.num_params(), 1627502u);
  EXPECT_EQ(
      ac.params().layout().find("policy/lstm/w")->size() + ac.params().layout().find("policy/lstm/b")->size(),
      525312u);
  EXPECT_EQ(ac.heads().num_logits(), 37);
  // The split src/nn/README.md gives ("Parameters").
  size_t policy = 0, value = 0;
  for (const ParamSlice& slice : ac.params().layout().slices())
    (slice.name.rfind("policy/", 0) == 0 ? policy : value) += slice.size();
  EXPECT_EQ(policy, 818377u);
  EXPECT_EQ(value, 809125u);
  ActorCritic small(net_preset("small"));
  EXPECT_EQ(small.num_params(), 486126u);
  EXPECT_LT(small.num_params(), ac.num_params() / 3);
  EXPECT_THROW(net_preset("huge"), std::invalid_argument);
}

TEST(NnNetwork, InitialisationFollowsSpec) {
  ActorCritic ac(net_preset("paper"));
  ac.params().init(5);
  // Policy logits: normc std 0.01 (each output column has norm 0.01); value head and LSTM: Xavier uniform.
  const auto logits = ac.params().slice("policy/logits/w");
  for (int c = 0; c < 37; c += 9) {
    double ss = 0.0;
    for (int r = 0; r < 256; ++r) ss += logits[r * 37 + c] * logits[r * 37 + c];
    EXPECT_NEAR(std::sqrt(ss), 0.01, 1e-6);
  }
  const auto lstm = ac.params().slice("value/lstm/w");
  const float limit = std::sqrt(6.0f / (512 + 1024));
  float mx = 0.0f;
  for (float v : lstm) mx = std::max(mx, std::fabs(v));
  EXPECT_LE(mx, limit);
  EXPECT_GT(mx, 0.95f * limit);
  // Attention QK: N(0, sqrt(0.125 / 128)).
  const auto qk = ac.params().slice("policy/attention/qk/w");
  double ss = 0.0;
  for (float v : qk) ss += static_cast<double>(v) * v;
  EXPECT_NEAR(std::sqrt(ss / qk.size()), std::sqrt(0.125 / 128), 0.002);
  for (float v : ac.params().slice("policy/cat_norm/gain")) EXPECT_EQ(v, 1.0f);
  for (float v : ac.params().slice("policy/lstm/b")) EXPECT_EQ(v, 0.0f);
}

// Gradient of L = sum w_l * logits + sum w_v * value through ActorCritic::forward_backward (two chunks in two
// groups), against central differences of the float network, slice by slice. With bf16 products the
// analytic gradient is the bf16 network's, the differences still the float network's: the bound is what
// bf16's 8-bit mantissas cost (per slice 10 % of its norm + 0.01, in all 3 %; float: 2 % + 0.004, 0.5 %).
TEST_P(NnNetworkPrecision, EndToEndGradientMatchesFiniteDifferences) {
  const NetConfig cfg = tiny_config();
  ParallelConfig par;
  par.train_chunk_sequences = 2;
  par.grad_groups = 2;
  ActorCritic ac(cfg, par);
  ac.params().init(3);
  // Non-trivial gains and biases.
  auto jitter = random_vector(ac.params().buffer_floats(), 4, -0.2f, 0.2f);
  for (size_t i = 0; i < jitter.size(); ++i) ac.params().values()[i] += jitter[i];
  ActorCritic analytic_net(cfg, par);  // the same parameters at the precision under test
  std::copy_n(ac.params().values(), ac.params().buffer_floats(), analytic_net.params().values());
  use(analytic_net);
  const bool bf16 = precision() == Precision::kBf16;
  const int seqs = 4, steps = 3, rows = seqs * steps;
  const ObsData data(cfg.obs, rows, 100);
  const ObsNormalizer norm = fitted_normalizer(cfg.obs, data, rows);
  const auto state_p = random_vector(seqs * ac.state_width(), 5);
  const auto state_v = random_vector(seqs * ac.state_width(), 6);
  const int nl = ac.heads().num_logits();
  const auto w_logits = random_vector(rows * nl, 7);
  const auto w_value = random_vector(rows, 8);
  double loss_value = 0.0;
  LossFn loss = [&](const ChunkOutputs& out, const ChunkGrads& g, std::span<double> stats) {
    for (int r = 0; r < out.rows; ++r) {
      for (int k = 0; k < nl; ++k) {
        g.d_logits.at(r, k) = w_logits[(out.first_row + r) * nl + k];
        stats[0] += static_cast<double>(g.d_logits.at(r, k)) * out.logits.at(r, k);
      }
      g.d_value[r] = w_value[out.first_row + r];
      stats[0] += static_cast<double>(w_value[out.first_row + r]) * out.value[r];
    }
  };
  std::vector<float> grads(ac.params().buffer_floats());
  std::vector<double> stats(1);
  auto eval = [&]() {
    ac.forward_backward(norm.view(), data.batch(), seqs, steps, state_p.data(), state_v.data(), loss, stats,
                        grads.data());
    return stats[0];
  };
  loss_value = eval();
  analytic_net.forward_backward(norm.view(), data.batch(), seqs, steps, state_p.data(), state_v.data(), loss,
                                stats, grads.data());
  const std::vector<float> analytic = grads;
  int slices_checked = 0, coords = 0, skipped = 0;
  double total_err2 = 0.0, total_ref2 = 0.0;
  for (const testing::SliceCheck& c :
       testing::check_param_gradient(ac.params().values(), ac.params().layout(), analytic, 6, eval)) {
    coords += c.coords;
    skipped += c.skipped;
    total_err2 += c.err2;
    total_ref2 += c.ref2;
    if (c.ref2 < 1e-6) continue;
    ++slices_checked;
    EXPECT_LT(std::sqrt(c.err2), (bf16 ? 0.1 : 0.02) * std::sqrt(c.ref2) + (bf16 ? 1e-2 : 4e-3)) << c.name;
  }
  EXPECT_LT(std::sqrt(total_err2), (bf16 ? 0.03 : 0.005) * std::sqrt(total_ref2));
  std::printf("gradient vs float finite differences (%s): relative error %.4f over %d slices\n",
              GetParam().name, std::sqrt(total_err2 / total_ref2), slices_checked);
  EXPECT_GT(slices_checked, 50);
  EXPECT_LT(skipped, coords / 10);
  EXPECT_GT(slices_checked, 40);
  EXPECT_NE(loss_value, 0.0);
}

TEST_P(NnNetworkPrecision, MaskedEntitiesChangeNothing) {
  const NetConfig cfg = tiny_config();
  ParallelConfig par;
  par.train_chunk_sequences = 3;
  ActorCritic ac(cfg, par);
  ac.params().init(9);
  use(ac);
  const int seqs = 6, steps = 2, rows = seqs * steps;
  const ObsData data(cfg.obs, rows, 200);
  const ObsNormalizer norm = fitted_normalizer(cfg.obs, data, rows);
  auto run = [&](const ObsData& d) {
    return outputs_and_grads(ac, norm.view(), d.batch(), seqs, steps, 0.1f, 0.0f, 1.0f);
  };
  const Result base = run(data);
  // Scramble the features of every entity the policy does not see: the policy ignores them, the value net
  // still sees those that are present.
  ObsData unseen = data;
  const ObsShape& s = cfg.obs;
  for (size_t i = 0; i < unseen.agents_seen.size(); ++i)
    if (unseen.agents_seen[i] == 0.0f)
      for (int f = 0; f < s.agent_features; ++f) unseen.agents[i * s.agent_features + f] = 1e5f + f;
  for (size_t i = 0; i < unseen.boxes_seen.size(); ++i)
    if (unseen.boxes_seen[i] == 0.0f)
      for (int f = 0; f < s.box_features; ++f) unseen.boxes[i * s.box_features + f] = -3e4f * f;
  for (size_t i = 0; i < unseen.sites_seen.size(); ++i)
    if (unseen.sites_seen[i] == 0.0f)
      for (int f = 0; f < s.site_features; ++f) unseen.sites[i * s.site_features + f] = 2e4f + f;
  const Result r1 = run(unseen);
  EXPECT_TRUE(same_bits(base.logits.data(), r1.logits.data(), base.logits.size()));
  EXPECT_FALSE(same_bits(base.value.data(), r1.value.data(), base.value.size()));
  // Nor the policy's gradients (the output gradients are fixed); the value net's change with what it sees.
  bool value_grads_changed = false;
  for (const ParamSlice& sl : ac.params().layout().slices()) {
    const bool same = same_bits(base.grads.data() + sl.offset, r1.grads.data() + sl.offset, sl.size());
    if (sl.name.rfind("policy/", 0) == 0) {
      EXPECT_TRUE(same) << sl.name;
    }
    value_grads_changed |= !same;
  }
  EXPECT_TRUE(value_grads_changed);
  // Scramble only absent (padding) slots: nothing changes anywhere, gradients included.
  ObsData padding = data;
  for (size_t i = 0; i < padding.agents_present.size(); ++i)
    if (padding.agents_present[i] == 0.0f)
      for (int f = 0; f < s.agent_features; ++f) padding.agents[i * s.agent_features + f] = 7e6f;
  for (size_t i = 0; i < padding.boxes_present.size(); ++i)
    if (padding.boxes_present[i] == 0.0f)
      for (int f = 0; f < s.box_features; ++f) padding.boxes[i * s.box_features + f] = NAN;
  for (size_t i = 0; i < padding.sites_present.size(); ++i)
    if (padding.sites_present[i] == 0.0f)
      for (int f = 0; f < s.site_features; ++f) padding.sites[i * s.site_features + f] = -NAN;
  const Result r2 = run(padding);
  EXPECT_TRUE(same_bits(base.logits.data(), r2.logits.data(), base.logits.size()));
  EXPECT_TRUE(same_bits(base.value.data(), r2.value.data(), base.value.size()));
  EXPECT_TRUE(same_bits(base.grads.data(), r2.grads.data(), base.grads.size()));
  // The value net ignores visibility; the policy does not.
  ObsData blind = data;
  std::fill_n(blind.agents_seen.data(), blind.agents_seen.size(), 0.0f);
  const Result r3 = run(blind);
  EXPECT_TRUE(same_bits(base.value.data(), r3.value.data(), base.value.size()));
  EXPECT_FALSE(same_bits(base.logits.data(), r3.logits.data(), base.logits.size()));
}

// bf16 products really run: the same parameters and inputs give other logits, values and gradients than
// fp32, close to them (bf16 keeps 8 significant bits of each operand).
TEST(NnNetwork, Bf16ProductsChangeTheResultsWithinTheirPrecision) {
  if (!bf16::available()) GTEST_SKIP() << "this CPU has no AVX512-BF16";
  const NetConfig cfg = tiny_config();
  ParallelConfig par;
  par.train_chunk_sequences = 3;
  const int seqs = 6, steps = 2, rows = seqs * steps;
  const ObsData data(cfg.obs, rows, 700);
  const ObsNormalizer norm = fitted_normalizer(cfg.obs, data, rows);
  ActorCritic a(cfg, par), b(cfg, par);
  a.params().init(5);
  b.params().init(5);
  b.set_precision(Precision::kBf16);
  const Result fa = outputs_and_grads(a, norm.view(), data.batch(), seqs, steps, 0.1f, 0.0f, 1.0f);
  const Result fb = outputs_and_grads(b, norm.view(), data.batch(), seqs, steps, 0.1f, 0.0f, 1.0f);
  EXPECT_FALSE(same_bits(fa.logits.data(), fb.logits.data(), fa.logits.size()));
  EXPECT_FALSE(same_bits(fa.value.data(), fb.value.data(), fa.value.size()));
  EXPECT_FALSE(same_bits(fa.grads.data(), fb.grads.data(), fa.grads.size()));
  double err = 0, ref = 0;
  for (size_t i = 0; i < fa.logits.size(); ++i) {
    err += double(fa.logits[i] - fb.logits[i]) * (fa.logits[i] - fb.logits[i]);
    ref += double(fa.logits[i]) * fa.logits[i];
  }
  EXPECT_LT(std::sqrt(err), 0.02 * std::sqrt(ref));
}

// Switching the bf16 kernel after a network packed its weights lays them out anew for the new kernel: the
// results equal those of a network that only ever ran on it (the AMX layouts pad k, so packing into the old
// layout would overrun it).
TEST(NnNetwork, SwitchingTheBf16KernelRepacksTheWeights) {
  if (!bf16::available()) GTEST_SKIP() << "this CPU has no AVX512-BF16";
  const bf16::Kernel saved = bf16::kernel();
  const NetConfig cfg = tiny_config();
  ParallelConfig par;
  par.train_chunk_sequences = 3;
  const int seqs = 6, steps = 2, rows = seqs * steps;
  const ObsData data(cfg.obs, rows, 900);
  const ObsNormalizer norm = fitted_normalizer(cfg.obs, data, rows);
  bf16::set_kernel(bf16::Kernel::kAvx512Bf16);
  ActorCritic a(cfg, par);
  a.params().init(5);
  a.set_precision(Precision::kBf16);
  (void)outputs_and_grads(a, norm.view(), data.batch(), seqs, steps, 0.1f, 0.0f, 1.0f);
  bf16::set_kernel(bf16::Kernel::kAmxEmulated);
  const Result switched = outputs_and_grads(a, norm.view(), data.batch(), seqs, steps, 0.1f, 0.0f, 1.0f);
  ActorCritic b(cfg, par);
  b.params().init(5);
  b.set_precision(Precision::kBf16);
  const Result fresh = outputs_and_grads(b, norm.view(), data.batch(), seqs, steps, 0.1f, 0.0f, 1.0f);
  bf16::set_kernel(saved);
  EXPECT_TRUE(same_bits(switched.logits.data(), fresh.logits.data(), fresh.logits.size()));
  EXPECT_TRUE(same_bits(switched.value.data(), fresh.value.data(), fresh.value.size()));
  EXPECT_TRUE(same_bits(switched.grads.data(), fresh.grads.data(), fresh.grads.size()));
}

// The trainer's path: observations normalised once into a rollout (rows in another order), a minibatch read
// through a row index with the identity view. Logits, values and gradients equal, to the bit, those of the
// same rows held contiguously, raw, and normalised inside the forward pass.
TEST(NnNetwork, IndexedNormalisedRowsEqualContiguousRawRows) {
  const NetConfig cfg = tiny_config();
  ParallelConfig par;
  par.train_chunk_sequences = 2;
  ActorCritic ac(cfg, par);
  ac.params().init(5);
  const int seqs = 5, steps = 3, rows = seqs * steps;
  const ObsData data(cfg.obs, rows, 400);
  const ObsNormalizer norm = fitted_normalizer(cfg.obs, data, rows);
  const ObsNormView view = norm.view();
  const ObsShape& s = cfg.obs;
  const int na = s.num_other_agents(), nl = ac.heads().num_logits();
  // Rollout row of minibatch row r: a permutation of 3 * rows rows (the others hold other data).
  const int rollout_rows = 3 * rows;
  std::vector<int32_t> index(rows);
  for (int r = 0; r < rows; ++r) index[r] = (r * 7 + 4) % rollout_rows;
  ObsData rollout(s, rollout_rows, 401);
  auto place = [&](const FloatBuffer& src, FloatBuffer& dst, int per_row, int features, int key) {
    for (int r = 0; r < rows; ++r) {
      const float* from = src.data() + static_cast<size_t>(r) * per_row;
      float* to = dst.data() + static_cast<size_t>(index[r]) * per_row;
      if (key < 0) {
        std::memcpy(to, from, sizeof(float) * per_row);
      } else {
        kernels::normalize_obs(from, view.mean[key], view.inv_std[key], nullptr, per_row / features, features,
                               to);
      }
    }
  };
  place(data.self, rollout.self, s.self_features, s.self_features, kObsSelf);
  place(data.lidar, rollout.lidar, s.lidar_rays, s.lidar_rays, kObsLidar);
  place(data.agents, rollout.agents, na * s.agent_features, s.agent_features, kObsAgents);
  place(data.boxes, rollout.boxes, s.max_boxes * s.box_features, s.box_features, kObsBoxes);
  place(data.ramps, rollout.ramps, s.max_ramps * s.ramp_features, s.ramp_features, kObsRamps);
  place(data.sites, rollout.sites, s.max_sites * s.site_features, s.site_features, kObsSites);
  place(data.sites_seen, rollout.sites_seen, s.max_sites, 1, -1);
  place(data.sites_present, rollout.sites_present, s.max_sites, 1, -1);
  place(data.agents_seen, rollout.agents_seen, na, 1, -1);
  place(data.boxes_seen, rollout.boxes_seen, s.max_boxes, 1, -1);
  place(data.ramps_seen, rollout.ramps_seen, s.max_ramps, 1, -1);
  place(data.agents_present, rollout.agents_present, na, 1, -1);
  place(data.boxes_present, rollout.boxes_present, s.max_boxes, 1, -1);
  place(data.ramps_present, rollout.ramps_present, s.max_ramps, 1, -1);
  place(data.reset, rollout.reset, 1, 1, -1);
  ObsBatch indexed = rollout.batch();
  indexed.index = index.data();

  auto run = [&](const ObsNormView& v, const ObsBatch& obs) {
    return outputs_and_grads(ac, v, obs, seqs, steps, 0.05f, -0.3f, 0.7f);
  };
  const Result raw = run(view, data.batch());
  const Result idx = run(ObsNormView::identity(), indexed);
  EXPECT_TRUE(same_bits(raw.logits.data(), idx.logits.data(), raw.logits.size()));
  EXPECT_TRUE(same_bits(raw.value.data(), idx.value.data(), raw.value.size()));
  EXPECT_TRUE(same_bits(raw.grads.data(), idx.grads.data(), raw.grads.size()));
  // And the inference path reads the same rows through rows_from.
  const int sw = ac.state_width(), nh = ac.heads().num_heads();
  std::vector<float> ps(static_cast<size_t>(rows) * sw, 0.0f), vs = ps, ps2 = ps, vs2 = ps;
  const std::vector<float> uniforms(static_cast<size_t>(rows) * nh, 0.25f);
  std::vector<int32_t> a1(static_cast<size_t>(rows) * nh), a2 = a1;
  std::vector<float> l1(static_cast<size_t>(rows) * nl), l2 = l1;
  ac.act(view, data.batch().rows_from(2, s), rows - 2, ps.data(), vs.data(), uniforms.data(),
         {a1.data(), nullptr, nullptr, l1.data()});
  ac.act(ObsNormView::identity(), indexed.rows_from(2, s), rows - 2, ps2.data(), vs2.data(), uniforms.data(),
         {a2.data(), nullptr, nullptr, l2.data()});
  EXPECT_TRUE(same_bits(l1.data(), l2.data(), static_cast<size_t>(rows - 2) * nl));
  EXPECT_EQ(a1, a2);
}

// Gradient groups given by the caller (the trainer's blocks of envs): each group's chunks start at the
// group's first sequence, and the result is the groups' own gradients summed in group order, an empty group
// included, to the bit.
TEST(NnNetwork, ExplicitGroupsSumTheirGradientsInGroupOrder) {
  const NetConfig cfg = tiny_config();
  ParallelConfig par;
  par.train_chunk_sequences = 2;
  par.grad_groups = 1;  // the reference calls below: one group each
  ActorCritic ac(cfg, par);
  ac.params().init(12);
  const int seqs = 9, steps = 2;
  const ObsData data(cfg.obs, seqs * steps, 500);
  const ObsNormalizer norm = fitted_normalizer(cfg.obs, data, seqs * steps);
  const std::vector<int> groups = {0, 3, 3, 8, 9};
  std::vector<float> grads(ac.params().buffer_floats());
  const int nl = ac.heads().num_logits();
  std::vector<float> logits(static_cast<size_t>(seqs) * steps * nl);
  auto loss_at = [&](int row0) {
    return [&, row0](const ChunkOutputs& out, const ChunkGrads& g, std::span<double>) {
      for (int r = 0; r < out.rows; ++r) {
        for (int k = 0; k < nl; ++k) {
          logits[(row0 + out.first_row + r) * nl + k] = out.logits.at(r, k);
          g.d_logits.at(r, k) = 0.02f * static_cast<float>(k) - 0.1f;
        }
        g.d_value[r] = -0.4f;
      }
    };
  };
  std::vector<double> stats;
  ac.forward_backward(norm.view(), data.batch(), seqs, steps, nullptr, nullptr, loss_at(0), stats,
                      grads.data(), groups);
  const std::vector<float> logits_grouped = logits;
  std::vector<float> sum(grads.size(), 0.0f), one(grads.size());
  for (size_t g = 0; g + 1 < groups.size(); ++g) {
    const int s0 = groups[g], n = groups[g + 1] - groups[g];
    ac.forward_backward(norm.view(), data.batch().rows_from(static_cast<size_t>(s0) * steps, cfg.obs), n,
                        steps, nullptr, nullptr, loss_at(s0 * steps), stats, one.data());
    for (size_t i = 0; i < sum.size(); ++i) sum[i] = g == 0 ? one[i] : sum[i] + one[i];
  }
  EXPECT_TRUE(same_bits(grads.data(), sum.data(), sum.size()));
  EXPECT_EQ(logits_grouped, logits);
  EXPECT_THROW(ac.forward_backward(norm.view(), data.batch(), seqs, steps, nullptr, nullptr, loss_at(0),
                                   stats, grads.data(), std::vector<int>{0, 5, 4, 9}),
               std::logic_error);
}

// sum_groups() zeroes the group buffers as it reads them, so that compute_groups() need not clear them:
// whatever the last sum read (everything, half, nothing) and however many groups the last call had, a
// gradient is the one the first call computed; and a range summed twice reads zeros.
TEST(NnNetwork, GroupGradientsStartFromZeroWhateverTheLastSumRead) {
  const NetConfig cfg = tiny_config();
  ParallelConfig par;
  par.train_chunk_sequences = 2;
  par.grad_groups = 4;
  ActorCritic ac(cfg, par);
  ac.params().init(5);
  const int seqs = 9, steps = 2;
  const ObsData data(cfg.obs, seqs * steps, 400);
  const ObsNormalizer norm = fitted_normalizer(cfg.obs, data, seqs * steps);
  const size_t n = ac.params().buffer_floats();
  const Result want = outputs_and_grads(ac, norm.view(), data.batch(), seqs, steps, 0.01f, -0.05f, 0.3f);
  auto again = [&] {
    return outputs_and_grads(ac, norm.view(), data.batch(), seqs, steps, 0.01f, -0.05f, 0.3f).grads;
  };
  const int nl = ac.heads().num_logits();
  const LossFn loss = [&](const ChunkOutputs& out, const ChunkGrads& g, std::span<double>) {
    for (int r = 0; r < out.rows; ++r) {
      for (int k = 0; k < nl; ++k) g.d_logits.at(r, k) = 1.0f;
      g.d_value[r] = 1.0f;
    }
  };
  EXPECT_TRUE(same_bits(again().data(), want.grads.data(), n)) << "after a whole sum";
  std::vector<float> part(n);
  ac.compute_groups(norm.view(), data.batch(), seqs, steps, nullptr, nullptr, loss, 0);
  ac.sum_groups(0, n / 2, nullptr, part.data());
  EXPECT_TRUE(same_bits(again().data(), want.grads.data(), n)) << "after half a sum";
  ac.compute_groups(norm.view(), data.batch(), seqs, steps, nullptr, nullptr, loss, 0,
                    std::vector<int>{0, 4, 9});
  EXPECT_TRUE(same_bits(again().data(), want.grads.data(), n)) << "after two groups never summed";
  ac.compute_groups(norm.view(), data.batch(), seqs, steps, nullptr, nullptr, loss, 0);
  ac.sum_groups(0, n, nullptr, part.data());
  EXPECT_NE(std::count(part.begin(), part.end(), 0.0f), ptrdiff_t(n));
  ac.sum_groups(0, n, nullptr, part.data());
  EXPECT_EQ(std::count(part.begin(), part.end(), 0.0f), ptrdiff_t(n)) << "a second sum of a range";
  EXPECT_TRUE(same_bits(again().data(), want.grads.data(), n)) << "after a range summed twice";
}

// A row's outputs in act() do not depend on the rows beside it (how many there are, where its chunk starts):
// a run split over processes acts on other slices of the same rows.
TEST_P(NnNetworkPrecision, ActRowsDoNotDependOnTheirChunk) {
  const NetConfig cfg = net_preset("small");
  ActorCritic ac(cfg);
  ac.params().init(21);
  use(ac);
  const int rows = 70;
  const ObsData data(cfg.obs, rows, 600);
  const ObsNormalizer norm = fitted_normalizer(cfg.obs, data, rows);
  const int nl = ac.heads().num_logits(), nh = ac.heads().num_heads(), sw = ac.state_width();
  auto logits_of = [&](int first, int n) {
    std::vector<float> ps(static_cast<size_t>(n) * sw, 0.0f), vs = ps, logits(static_cast<size_t>(n) * nl),
                                                              value(static_cast<size_t>(n));
    const std::vector<float> uniforms(static_cast<size_t>(n) * nh, 0.5f);
    std::vector<int32_t> actions(static_cast<size_t>(n) * nh);
    ac.act(norm.view(), data.batch().rows_from(static_cast<size_t>(first), cfg.obs), n, ps.data(), vs.data(),
           uniforms.data(), {actions.data(), nullptr, value.data(), logits.data()});
    logits.insert(logits.end(), value.begin(), value.end());
    logits.insert(logits.end(), ps.begin(), ps.end());
    return logits;
  };
  const std::vector<float> all = logits_of(0, rows);
  int checked = 0;
  for (int first : {0, 3, 61, 66}) {
    for (int n = 1; first + n <= rows && n <= 13; n += 3) {
      const std::vector<float> part = logits_of(first, n);
      for (int i = 0; i < n; ++i) {
        const size_t r = static_cast<size_t>(first + i);
        ASSERT_TRUE(same_bits(part.data() + static_cast<size_t>(i) * nl, all.data() + r * nl, nl))
            << "logits of row " << r << " acting on rows [" << first << ", " << first + n << ")";
        ASSERT_EQ(part[static_cast<size_t>(n) * nl + i], all[static_cast<size_t>(rows) * nl + r]) << "value";
        ASSERT_TRUE(same_bits(part.data() + static_cast<size_t>(n) * (nl + 1) + static_cast<size_t>(i) * sw,
                              all.data() + static_cast<size_t>(rows) * (nl + 1) + r * sw, sw))
            << "state of row " << r;
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 80);
}

// The training path's forward over 10-step sequences gives the same bits as ten act() steps with carried
// states: PPO's first minibatch must recompute exactly the log-probabilities the rollout sampled with. The
// training chunks (4 and 3 sequences: 40 and 30 rows) end in partial row panels, the act chunks (5 agents)
// too, so every row meets both kinds of product.
TEST_P(NnNetworkPrecision, ChunkOfTenStepsEqualsTenActSteps) {
  NetConfig cfg = net_preset("small");
  ParallelConfig par;
  par.infer_chunk_agents = 5;
  par.train_chunk_sequences = 4;
  ActorCritic ac(cfg, par);
  ac.params().init(11);
  use(ac);
  const int agents = 7, steps = 10, rows = agents * steps;
  const ObsData data(cfg.obs, rows, 300, 0.1);
  const ObsNormalizer norm = fitted_normalizer(cfg.obs, data, rows);
  const int nl = ac.heads().num_logits(), nh = ac.heads().num_heads(), sw = ac.state_width();
  // Training-path forward over 10-step sequences (row = agent * steps + t).
  std::vector<float> logits_chunk(rows * nl), value_chunk(rows);
  std::vector<double> stats;
  std::vector<float> grads(ac.params().buffer_floats());
  ac.forward_backward(
      norm.view(), data.batch(), agents, steps, nullptr, nullptr,
      [&](const ChunkOutputs& out, const ChunkGrads& g, std::span<double>) {
        for (int r = 0; r < out.rows; ++r) {
          std::memcpy(&logits_chunk[(out.first_row + r) * nl], out.logits.row(r), nl * sizeof(float));
          value_chunk[out.first_row + r] = out.value[r];
          for (int k = 0; k < nl; ++k) g.d_logits.at(r, k) = 0.0f;
          g.d_value[r] = 0.0f;
        }
      },
      stats, grads.data());
  // Inference path, one step at a time with carried states, gathering step t of every agent.
  std::vector<float> ps(agents * sw, 0.0f), vs(agents * sw, 0.0f);
  const std::vector<float> uniforms(agents * nh, 0.5f);
  std::vector<int32_t> actions(agents * nh);
  std::vector<float> logp(agents), value(agents), logits(agents * nl);
  double worst = 0.0;
  for (int t = 0; t < steps; ++t) {
    ObsData step(cfg.obs, agents, 0);
    auto gather = [&](const FloatBuffer& src, FloatBuffer& dst, size_t per_row) {
      if (per_row == 0) return;  // an entity type this shape lacks: empty arrays
      for (int a = 0; a < agents; ++a)
        std::memcpy(dst.data() + a * per_row, src.data() + (a * steps + t) * per_row,
                    per_row * sizeof(float));
    };
    const ObsShape& s = cfg.obs;
    gather(data.self, step.self, s.self_features);
    gather(data.lidar, step.lidar, s.lidar_rays);
    gather(data.agents, step.agents, s.num_other_agents() * s.agent_features);
    gather(data.boxes, step.boxes, s.max_boxes * s.box_features);
    gather(data.ramps, step.ramps, s.max_ramps * s.ramp_features);
    gather(data.sites, step.sites, s.max_sites * s.site_features);
    gather(data.sites_seen, step.sites_seen, s.max_sites);
    gather(data.sites_present, step.sites_present, s.max_sites);
    gather(data.agents_seen, step.agents_seen, s.num_other_agents());
    gather(data.boxes_seen, step.boxes_seen, s.max_boxes);
    gather(data.ramps_seen, step.ramps_seen, s.max_ramps);
    gather(data.agents_present, step.agents_present, s.num_other_agents());
    gather(data.boxes_present, step.boxes_present, s.max_boxes);
    gather(data.ramps_present, step.ramps_present, s.max_ramps);
    gather(data.reset, step.reset, 1);
    ac.act(norm.view(), step.batch(), agents, ps.data(), vs.data(), uniforms.data(),
           {actions.data(), logp.data(), value.data(), logits.data()});
    for (int a = 0; a < agents; ++a) {
      for (int k = 0; k < nl; ++k)
        worst = std::max(worst, static_cast<double>(
                                    std::fabs(logits[a * nl + k] - logits_chunk[(a * steps + t) * nl + k])));
      worst = std::max(worst, static_cast<double>(std::fabs(value[a] - value_chunk[a * steps + t])));
    }
  }
  EXPECT_EQ(worst, 0.0) << "largest difference of a logit or value between the two paths";
}

TEST_P(NnNetworkPrecision, BitIdenticalForAnyThreadCount) {
  NetConfig cfg = tiny_config();
  cfg.embed = 16;
  cfg.dense = 24;
  cfg.lstm = 20;
  ParallelConfig par;
  par.infer_chunk_agents = 8;
  par.train_chunk_sequences = 3;
  const int agents = 61, seqs = 23, steps = 5;
  const ObsData obs_act(cfg.obs, agents, 400);
  const ObsData obs_train(cfg.obs, seqs * steps, 500);
  const ObsNormalizer norm = fitted_normalizer(cfg.obs, obs_train, seqs * steps);
  struct Result {
    std::vector<int32_t> actions;
    std::vector<float> logp, value, ps, vs, grads, params;
    std::vector<double> stats;
  };
  auto run_in_arena = [&] {
    ActorCritic ac(cfg, par);
    ac.params().init(13);
    use(ac);
    Result r;
    const int nh = ac.heads().num_heads(), sw = ac.state_width();
    r.actions.resize(agents * nh);
    r.logp.resize(agents);
    r.value.resize(agents);
    r.ps = random_vector(agents * sw, 14);
    r.vs = random_vector(agents * sw, 15);
    const auto uniforms = random_vector(agents * nh, 16, 0.0f, 1.0f);
    ac.act(norm.view(), obs_act.batch(), agents, r.ps.data(), r.vs.data(), uniforms.data(),
           {r.actions.data(), r.logp.data(), r.value.data(), nullptr});
    // A PPO-like loss: -logp(actions) * adv - 0.01 entropy + 0.5 (v - target)^2.
    const auto adv = random_vector(seqs * steps, 17);
    const auto target = random_vector(seqs * steps, 18);
    std::vector<int32_t> train_actions(seqs * steps * nh);
    for (size_t i = 0; i < train_actions.size(); ++i) train_actions[i] = static_cast<int32_t>(i % 2);
    r.stats.resize(2);
    r.grads.resize(ac.params().buffer_floats());
    const CategoricalHeads& heads = ac.heads();
    ac.forward_backward(
        norm.view(), obs_train.batch(), seqs, steps, nullptr, nullptr,
        [&](const ChunkOutputs& out, const ChunkGrads& g, std::span<double> stats) {
          std::vector<float> lp(out.rows), ent(out.rows), dlp(out.rows), dent(out.rows, -0.01f);
          const int32_t* a = train_actions.data() + static_cast<ptrdiff_t>(out.first_row) * nh;
          heads.log_prob_entropy(out.logits, a, lp.data(), ent.data());
          for (int i = 0; i < out.rows; ++i) {
            dlp[i] = -adv[out.first_row + i];
            const float diff = out.value[i] - target[out.first_row + i];
            g.d_value[i] = diff;
            stats[0] += -lp[i] * adv[out.first_row + i];
            stats[1] += 0.5 * diff * diff;
          }
          heads.backward(out.logits, a, dlp.data(), dent.data(), g.d_logits);
        },
        r.stats, r.grads.data());
    Adam adam(ac.params().layout(), {});
    adam.step(ac.params().values(), r.grads.data());
    r.params.assign(ac.params().values(), ac.params().values() + ac.params().buffer_floats());
    return r;
  };
  // `threads` threads for real, whatever the host's core count: an arena of that many slots.
  auto run = [&](int threads, int groups) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    par.grad_groups = groups;
    Result r;
    tbb::task_arena(threads).execute([&] { r = run_in_arena(); });
    return r;
  };
  // 1 group (then only a chunk's two networks run in parallel) and 4; 8 threads (more than tasks) 3 times.
  auto same = [](const std::vector<float>& a, const std::vector<float>& b) {
    return same_bits(a.data(), b.data(), a.size());
  };
  Result one;
  for (int groups : {1, 4}) {
    one = run(1, groups);
    // bf16's weight gradients summed over several chunks (GradStage; here chunks of 15 rows, an odd count,
    // 8 per group with 1 group, 2 with 4) against one product per chunk: the same bits.
    par.stage_weight_grads = false;
    const Result unstaged = run(2, groups);
    par.stage_weight_grads = true;
    EXPECT_TRUE(same(one.grads, unstaged.grads) && same(one.params, unstaged.params))
        << "staged against unstaged weight gradients, " << groups << " groups";
    for (int threads : {2, 3, 8, 8, 8}) {
      const Result many = run(threads, groups);
      const std::string where = std::to_string(threads) + " threads, " + std::to_string(groups) + " groups";
      EXPECT_EQ(one.actions, many.actions) << where;
      EXPECT_TRUE(same(one.logp, many.logp) && same(one.value, many.value)) << "act's outputs, " << where;
      EXPECT_TRUE(same(one.ps, many.ps) && same(one.vs, many.vs)) << "states, " << where;
      EXPECT_TRUE(same(one.grads, many.grads) && same(one.params, many.params)) << "gradients, " << where;
      EXPECT_EQ(one.stats, many.stats) << where;
    }
  }
  double norm2 = 0.0;
  for (float g : one.grads) norm2 += static_cast<double>(g) * g;
  EXPECT_GT(norm2, 0.0);
}

// A few hundred Adam steps on a fixed batch: the value net fits its targets and the policy raises the
// probability of the target actions.
TEST_P(NnNetworkPrecision, TrainingReducesTheLoss) {
  NetConfig cfg = tiny_config();
  cfg.embed = 16;
  cfg.dense = 32;
  cfg.lstm = 16;
  ActorCritic ac(cfg);
  ac.params().init(21);
  use(ac);
  const int seqs = 8, steps = 4, rows = seqs * steps;
  const ObsData data(cfg.obs, rows, 600);
  const ObsNormalizer norm = fitted_normalizer(cfg.obs, data, rows);
  const int nh = ac.heads().num_heads();
  std::vector<float> target(rows);
  std::vector<int32_t> actions(rows * nh);
  for (int r = 0; r < rows; ++r) {
    target[r] = data.self[r * cfg.obs.self_features] > 0.0f ? 1.0f : -1.0f;
    for (int h = 0; h < nh; ++h) actions[r * nh + h] = (r + h) % ac.heads().sizes()[h];
  }
  AdamConfig acfg;
  acfg.lr = 3e-3f;
  acfg.max_grad_norm = 5.0f;
  Adam adam(ac.params().layout(), acfg);
  std::vector<double> stats(2);
  auto step = [&]() {
    ac.forward_backward(
        norm.view(), data.batch(), seqs, steps, nullptr, nullptr,
        [&](const ChunkOutputs& out, const ChunkGrads& g, std::span<double> st) {
          std::vector<float> lp(out.rows), dlp(out.rows, -1.0f / rows);
          const int32_t* a = actions.data() + static_cast<ptrdiff_t>(out.first_row) * nh;
          ac.heads().log_prob_entropy(out.logits, a, lp.data(), nullptr);
          ac.heads().backward(out.logits, a, dlp.data(), nullptr, g.d_logits);
          for (int i = 0; i < out.rows; ++i) {
            const float diff = out.value[i] - target[out.first_row + i];
            g.d_value[i] = diff / rows;
            st[0] += -lp[i] / rows;
            st[1] += 0.5 * diff * diff / rows;
          }
        },
        stats, ac.params().grads());
    adam.step(ac.params().values(), ac.params().grads());
    return std::make_pair(stats[0], stats[1]);
  };
  const auto first = step();
  std::pair<double, double> last;
  for (int i = 0; i < 150; ++i) last = step();
  EXPECT_LT(last.first, 0.5 * first.first);
  EXPECT_LT(last.second, 0.2 * first.second);
}

}  // namespace
}  // namespace hns::nn
