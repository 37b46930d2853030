// Throughput of the policy + value networks on synthetic observations (by default shaped like the `full`
// scene: 5 other agents, 9 boxes, 2 ramps, 30 lidar rays; about 60 % of entities seen), for
// `hns bench --nn paper|small --threads T [--masks synthetic|quadrant|full]`:
//   inference: one step (policy + value forward, action sampling) for a batch of agents (default 1024);
//   training:  forward + backward + Adam over a minibatch of BPTT chunks (default 256 x 10 steps), with a
//              PPO-like loss (clipped-free surrogate, entropy bonus, value regression);
//   GEMM:      a plain Eigen float GEMM of the LSTM's training shape (2560 x 256 times 256 x 1024), one
//              independent product per thread, as the machine's peak reference; at precision bf16 also
//              the bf16 kernel's GEMM of the same shape (bf16::gemm, operands converted and packed once,
//              outside the timing), the peak reference of the bf16 path.
// FLOPs count 2 per multiply-add of the products actually performed (dense layers, conv, LSTM, attention
// q.k and p.v; the x_self part of each entity embedding once per agent); a backward pass counts twice the
// forward. Elementwise work (norms, softmax, gates) is not counted. The plain figure counts every entity
// slot (comparable across versions); the useful one only unmasked entities, whose work the network does. Each
// figure is the median over repeated timed runs of at least min_seconds in total.
#pragma once

#include "nn/actor_critic.hpp"
#include "nn/obs_store.hpp"
#include "nn/precision.hpp"

#include <cstdint>
#include <string>

namespace hns::nn {

// How often an entity slot holds an entity (present: the value net's mask) and how often a present one is
// seen (the policy's mask), per entity type, for the synthetic observations.
struct MaskDensity {
  std::string name = "synthetic";  // where the figures come from (printed and in the JSON)
  double agents_present = 1.0, boxes_present = 1.0, ramps_present = 1.0;
  double agents_seen = 0.6, boxes_seen = 0.6, ramps_seen = 0.6;
  bool alternate_last_box = true;  // the last box slot absent in every other row (the synthetic default)
};

struct NnBenchOptions {
  std::string model = "paper";  // preset name (net_preset)
  ObsShape shape;               // observation shape (default: the full scene's)
  MaskDensity masks;
  int threads = 1;            // TBB threads (>= 1)
  int infer_agents = 1024;    // agents per inference step
  int train_sequences = 256;  // BPTT chunks per training minibatch
  int train_steps = 10;       // steps per chunk
  double min_seconds = 1.0;   // minimum timed duration of each of the three measurements
  uint64_t seed = 1;
  Precision precision = Precision::kFp32;  // of the networks' products (bf16 needs bf16::available())
  ParallelConfig parallel;                 // work partition (results do not depend on threads)
};

struct NnBenchResult {
  std::string model;
  int threads = 0;
  size_t params = 0;  // policy + value
  double infer_agent_steps_per_s = 0.0;
  double train_agent_steps_per_s = 0.0;
  std::string masks;                  // MaskDensity::name
  std::string precision;              // precision_name: fp32 | bf16
  std::string precision_description;  // precision_description: what runs the products
  double infer_gflops = 0.0;          // achieved, inference
  double train_gflops = 0.0;          // achieved, forward + backward (Adam not counted)
  // Achieved counting only the FLOPs of entities that are used (unmasked): the useful rate.
  double infer_useful_gflops = 0.0;
  double train_useful_gflops = 0.0;
  double gemm_gflops = 0.0;       // Eigen GEMM reference, all threads together
  double gemm_bf16_gflops = 0.0;  // bf16 GEMM reference (bf16::gemm), all threads; 0 at precision fp32
  double infer_flops_per_agent_step = 0.0;
  double train_flops_per_agent_step = 0.0;
  double infer_seconds = 0.0;  // median time of one inference step
  double train_seconds = 0.0;  // median time of one training minibatch (incl. Adam)
};

// Synthetic observations of `rows` agent-steps (what the benchmark runs on): values in plausible ranges,
// masks drawn with the densities (a slot is seen only if present), resets at about 1 in 20 steps; no sites.
ObsStore synthetic_obs(const ObsShape& shape, const MaskDensity& masks, int rows, uint64_t seed);

// Throws std::invalid_argument for an unknown model, non-positive sizes or bf16 on a CPU without it.
NnBenchResult run_nn_bench(const NnBenchOptions& options);

}  // namespace hns::nn
