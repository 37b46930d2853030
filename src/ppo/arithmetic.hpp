// What computes a rank's results, and the check that every rank of a job computes alike (hns train runs it
// before any training: docs/training.md "Across processes and machines").
#pragma once

#include <string>

#include "nn/precision.hpp"
#include "ppo/comm.hpp"

namespace hns::ppo {

// What computes a rank's results at precision p: the products' precision, for bf16 the kernel (AMX tiles or
// vdpbf16ps), and the build's instruction set as the start line names it, e.g. "bf16 on the avx512-bf16
// kernel, avx512 (AVX-512, 16 floats per vector, FMA) build".
// Results are bit-identical across ranks only where every rank computes with the same one.
std::string arithmetic_description(nn::Precision p);
// Every rank's arithmetic (`mine`: arithmetic_description) against rank 0's, before any training: throws
// physics::ConfigError naming the first rank that differs, both arithmetics and what makes them agree (on
// every rank, so that the whole job stops with one message), or saying that the ranks run different builds
// where one sends something else (a build from before this check).
void check_same_arithmetic(Comm& comm, const std::string& mine);

}  // namespace hns::ppo
