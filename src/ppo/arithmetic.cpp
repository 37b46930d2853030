#include "ppo/arithmetic.hpp"

#include <cmath>
#include <stdexcept>
#include <vector>

#include "nn/bf16_gemm.hpp"
#include "nn/kernels.hpp"
#include "physics/scene.hpp"

namespace hns::ppo {

std::string arithmetic_description(nn::Precision p) {
  // The build's whole description ("avx512 (AVX-512, 16 floats per vector, FMA)"): width and FMA round too.
  const std::string build = nn::kernels::isa_description();
  if (p != nn::Precision::kBf16) return "fp32 on the " + build + " build";
  return "bf16 on the " + std::string(nn::bf16::kernel_name(nn::bf16::kernel())) + " kernel, " + build +
         " build";
}

void check_same_arithmetic(Comm& comm, const std::string& mine) {
  if (comm.size() <= 1) return;
  // Each rank's description as a fixed number of characters (codes 1-255, then zeros).
  constexpr size_t kChars = 192;
  if (mine.size() > kChars)
    throw std::logic_error("check_same_arithmetic: a description over 192 characters");
  std::vector<double> chars(kChars, 0.0);
  for (size_t i = 0; i < mine.size(); ++i) chars[i] = static_cast<unsigned char>(mine[i]);
  std::vector<double> all;
  comm.allgather(chars, all);
  // A rank of another hns build, one from before this check, sends something else (its first gather is
  // check_same_start's checksum): refused by name rather than read as characters.
  const size_t n = static_cast<size_t>(comm.size());
  bool sized = all.size() == n * kChars;
  for (size_t i = 0; sized && i < all.size(); ++i)
    sized = all[i] >= 0.0 && all[i] <= 255.0 && all[i] == std::floor(all[i]);  // range first: no cast
  if (!sized) {
    throw physics::ConfigError(
        "the ranks run different hns builds (their start-up checks differ): every rank must run the same "
        "build");
  }
  auto rank_text = [&](size_t r) {
    std::string t;
    for (size_t i = 0; i < kChars && all[r * kChars + i] != 0.0; ++i)
      t += static_cast<char>(static_cast<unsigned char>(all[r * kChars + i]));
    return t;
  };
  const std::string first = rank_text(0);
  for (size_t r = 1; r < n; ++r) {
    const std::string other = rank_text(r);
    if (other == first) continue;
    throw physics::ConfigError(
        "rank " + std::to_string(r) + " computes in " + other + " and rank 0 in " + first +
        ": results are bit-identical only where every rank computes alike. Give every rank the same build "
        "and --precision fp32 (or bf16 where every machine has AVX512-BF16: auto picks per machine), and "
        "for bf16 on machines with and without AMX tiles HNS_BF16_KERNEL=avx512-bf16 on every rank (Open "
        "MPI: mpirun -x HNS_BF16_KERNEL=avx512-bf16)");
  }
}

}  // namespace hns::ppo
