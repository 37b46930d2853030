#include "nn/precision.hpp"

#include <stdexcept>

#include "nn/bf16_amx.hpp"
#include "nn/bf16_gemm.hpp"
#include "nn/kernels.hpp"

namespace hns::nn {
std::string_view precision_name(Precision p) {
  return p == Precision::kBf16 ? "bf16" : "fp32";
}

CpuFeatures CpuFeatures::detect() {
  CpuFeatures f;
  f.avx512_bf16 = bf16::available();
  f.amx_bf16 = bf16::amx_available();
  return f;
}

std::vector<std::string> precision_names() {
  return {"fp32", "bf16", "auto"};
}

Precision resolve_precision(std::string_view requested, const CpuFeatures& cpu) {
  if (requested == "fp32") return Precision::kFp32;
  if (requested == "auto") {
    if (!cpu.avx512_bf16) return Precision::kFp32;
    if (bf16::available()) bf16::kernel();  // an unusable HNS_BF16_KERNEL is refused here
    return Precision::kBf16;
  }
  if (requested == "bf16") {
    if (!cpu.avx512_bf16) {
      throw std::invalid_argument(
          "precision bf16 needs a CPU with AVX512-BF16 (vdpbf16ps: AMD Zen 4 or later, Intel Cooper Lake, "
          "Sapphire Rapids or later), and this one does not have it (bf16 is not emulated): use precision "
          "fp32 or auto");
    }
    if (bf16::available()) bf16::kernel();  // an unusable HNS_BF16_KERNEL is refused here
    return Precision::kBf16;
  }
  throw std::invalid_argument("precision '" + std::string(requested) + "' is not one of fp32, bf16, auto");
}

std::string precision_description(Precision p) {
  if (p == Precision::kBf16) {
    switch (bf16::kernel()) {
      case bf16::Kernel::kAmx:
        return "bf16 (bf16 operands, float accumulation: AMX-BF16 tiles)";
      case bf16::Kernel::kAmxEmulated:
        return "bf16 (bf16 operands, float accumulation: AMX-BF16 tiles, emulated)";
      default: {
        // A CPU whose tiles cannot run here says why: they would be the faster kernel.
        const std::string why = bf16::amx::unusable_reason(bf16::amx::support());
        return "bf16 (bf16 operands, float accumulation: AVX512-BF16 vdpbf16ps" +
               (why.empty() ? std::string() : "; this CPU's AMX-BF16 tiles are unusable here: " + why) + ")";
      }
    }
  }
  return "fp32 (" + kernels::isa_description() + ")";
}

}  // namespace hns::nn
