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
