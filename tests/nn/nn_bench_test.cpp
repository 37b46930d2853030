// The benchmark entry point behind `hns bench --nn`: runs on tiny batches and fills every field.
#include "nn/nn_bench.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

namespace hns::nn {
namespace {

TEST(NnBench, SmallModelTinyBatchesFillsEveryField) {
  NnBenchOptions o;
  o.model = "small";
  o.threads = 2;
  o.infer_agents = 40;
  o.train_sequences = 6;
  o.train_steps = 10;
  o.min_seconds = 0.0;
  const NnBenchResult r = run_nn_bench(o);
  EXPECT_EQ(r.model, "small");
  EXPECT_EQ(r.threads, 2);
  EXPECT_EQ(r.params, ActorCritic(net_preset("small")).num_params());
  EXPECT_GT(r.infer_agent_steps_per_s, 0.0);
  EXPECT_GT(r.train_agent_steps_per_s, 0.0);
  EXPECT_GT(r.infer_gflops, 0.0);
  EXPECT_GT(r.train_gflops, 0.0);
  EXPECT_GT(r.gemm_gflops, 0.0);
  // Training counts forward + backward (3x the forward's flops per agent-step).
  EXPECT_NEAR(r.train_flops_per_agent_step, 3.0 * r.infer_flops_per_agent_step,
              1e-6 * r.train_flops_per_agent_step);
  // 60 % of entities seen: the useful rate is below the all-slot one.
  EXPECT_GT(r.train_useful_gflops, 0.0);
  EXPECT_LT(r.train_useful_gflops, r.train_gflops);
  EXPECT_LT(r.infer_useful_gflops, r.infer_gflops);
  EXPECT_EQ(r.masks, "synthetic");
}

// The used-FLOP count: every slot with masks all 1 (or none), less for each masked entity, by exactly its
// embedding, projections and attention pairs.
TEST(NnBench, UsedFlopsCountOnlyUnmaskedEntities) {
  NetConfig cfg = net_preset("small");
  cfg.obs.max_agents = 2;  // 1 other agent
  cfg.obs.max_boxes = 1;
  cfg.obs.max_ramps = 1;
  const ActorCritic ac(cfg);
  const int rows = 2;
  const float ones[2] = {1.0f, 1.0f}, some[2] = {1.0f, 0.0f};
  ObsBatch all;
  all.agents_seen = all.boxes_seen = all.ramps_seen = ones;
  EXPECT_DOUBLE_EQ(ac.policy().forward_flops_used(all.policy_inputs(), rows),
                   ac.policy().forward_flops(rows));
  EXPECT_DOUBLE_EQ(ac.policy().forward_flops_used(ObsBatch{}.policy_inputs(), rows),
                   ac.policy().forward_flops(rows));
  // Row 1 sees no box: one entity fewer (4 -> 3 with self), 16 -> 9 attention pairs in that row.
  ObsBatch less = all;
  less.boxes_seen = some;
  const double d = cfg.embed;
  const double per_entity = 2.0 * cfg.obs.box_features * d + 2.0 * d * (2 * d + d + d);
  const double saved = per_entity + 2.0 * 2.0 * (16 - 9) * d;
  EXPECT_DOUBLE_EQ(
      ac.policy().forward_flops(rows) - ac.policy().forward_flops_used(less.policy_inputs(), rows), saved);
}

TEST(NnBench, RejectsBadOptions) {
  NnBenchOptions o;
  o.model = "medium";
  EXPECT_THROW(run_nn_bench(o), std::invalid_argument);
  o.model = "small";
  o.threads = 0;
  EXPECT_THROW(run_nn_bench(o), std::invalid_argument);
}

}  // namespace
}  // namespace hns::nn
