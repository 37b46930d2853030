#include "ppo/arithmetic.hpp"

#include <algorithm>
#include <vector>

#include "nn/bf16_gemm.hpp"
#include "nn/kernels.hpp"
#include "physics/scene.hpp"

namespace hns::ppo {

std::string arithmetic_description(nn::Precision p) {
  std::string isa = nn::kernels::isa_description();  // "avx512 (AVX-512, ...)": the build's name first
  isa = isa.substr(0, isa.find(' '));
  if (p != nn::Precision::kBf16) return "fp32 (" + isa + " build)";
  return "bf16 on the " + std::string(nn::bf16::kernel_name(nn::bf16::kernel())) + " kernel (" + isa +
         " build)";
}

void check_same_arithmetic(Comm& comm, const std::string& mine) {
  if (comm.size() <= 1) return;
  // Each rank's description as a fixed number of characters (the descriptions are far shorter).
  constexpr size_t kChars = 96;
  std::vector<double> chars(kChars, 0.0);
  for (size_t i = 0; i < std::min(kChars, mine.size()); ++i) chars[i] = static_cast<unsigned char>(mine[i]);
  std::vector<double> all;
  comm.allgather(chars, all);
  auto rank_text = [&](int r) {
    std::string t;
    for (size_t i = 0; i < kChars && all[size_t(r) * kChars + i] != 0.0; ++i)
      t += static_cast<char>(all[size_t(r) * kChars + i]);
    return t;
  };
  const std::string first = rank_text(0);
  for (int r = 1; r < comm.size(); ++r) {
    const std::string other = rank_text(r);
    if (other == first) continue;
    throw physics::ConfigError(
        "rank " + std::to_string(r) + " computes in " + other + " and rank 0 in " + first +
        ": results are bit-identical only where every rank computes alike. Give every rank the same "
        "build and --precision fp32 or bf16 (auto picks per machine), and, for bf16 on machines with and "
        "without AMX tiles, HNS_BF16_KERNEL=avx512-bf16 on every rank (Open MPI: mpirun -x HNS_BF16_KERNEL)");
  }
}

}  // namespace hns::ppo
