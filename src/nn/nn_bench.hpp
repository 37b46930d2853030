// Throughput of the policy + value networks on synthetic observations shaped like the `full` scene (5 other
// agents, 9 boxes, 2 ramps, 30 lidar rays), for `hns bench --nn paper|small --threads T`:
//   inference: one step (policy + value forward, action sampling) for a batch of agents (default 1024);
//   training:  forward + backward + Adam over a minibatch of BPTT chunks (default 256 x 10 steps), with a
//              PPO-like loss (clipped-free surrogate, entropy bonus, value regression);
//   GEMM:      a plain Eigen float GEMM of the LSTM's training shape (2560 x 256 times 256 x 1024), one
//              independent product per thread, as the machine's peak reference.
// FLOPs count 2 per multiply-add of the products actually performed (dense layers, conv, LSTM, attention
// q.k and p.v; the x_self part of each entity embedding once per agent); a backward pass counts twice the
// forward. Elementwise work (norms, softmax, gates) is not counted. Each figure is the median over repeated
// timed runs of at least min_seconds in total.
#pragma once

#include "nn/actor_critic.hpp"

#include <cstdint>
#include <string>

namespace hns::nn {

struct NnBenchOptions {
  std::string model = "paper";  // preset name (net_preset)
  int threads = 1;              // TBB threads (>= 1)
  int infer_agents = 1024;      // agents per inference step
  int train_sequences = 256;    // BPTT chunks per training minibatch
  int train_steps = 10;         // steps per chunk
  double min_seconds = 1.0;     // minimum timed duration of each of the three measurements
  uint64_t seed = 1;
  ParallelConfig parallel;  // work partition (results do not depend on threads)
};

struct NnBenchResult {
  std::string model;
  int threads = 0;
  size_t params = 0;  // policy + value
  double infer_agent_steps_per_s = 0.0;
  double train_agent_steps_per_s = 0.0;
  double infer_gflops = 0.0;  // achieved, inference
  double train_gflops = 0.0;  // achieved, forward + backward (Adam not counted)
  double gemm_gflops = 0.0;   // Eigen GEMM reference, all threads together
  double infer_flops_per_agent_step = 0.0;
  double train_flops_per_agent_step = 0.0;
  double infer_seconds = 0.0;  // median time of one inference step
  double train_seconds = 0.0;  // median time of one training minibatch (incl. Adam)
};

// Throws std::invalid_argument for an unknown model or non-positive sizes.
NnBenchResult run_nn_bench(const NnBenchOptions& options);

}  // namespace hns::nn
