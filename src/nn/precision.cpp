#include "nn/precision.hpp"

#include <stdexcept>

#include "nn/bf16_gemm.hpp"
#include "nn/kernels.hpp"

namespace hns::nn {
namespace {

// CPUID leaf 7 subleaf 1, EAX bit 5: AVX512_BF16 (reported by __builtin_cpu_supports too); leaf 7 subleaf 0,
// EDX bit 22: AMX-BF16.
bool cpu_has_amx_bf16() {
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  __asm__ volatile("cpuid" : "=a"(eax), "=b"(ebx), "=c"(ecx), "=d"(edx) : "a"(0));
  if (eax < 7) return false;
  __asm__ volatile("cpuid" : "=a"(eax), "=b"(ebx), "=c"(ecx), "=d"(edx) : "a"(7), "c"(0));
  return (edx >> 22) & 1u;
}

}  // namespace

std::string_view precision_name(Precision p) {
  return p == Precision::kBf16 ? "bf16" : "fp32";
}

CpuFeatures CpuFeatures::detect() {
  CpuFeatures f;
  f.avx512_bf16 = bf16::available();
  f.amx_bf16 = cpu_has_amx_bf16();
  return f;
}

std::vector<std::string> precision_names() {
  return {"fp32", "bf16", "auto"};
}

Precision resolve_precision(std::string_view requested, const CpuFeatures& cpu) {
  if (requested == "fp32") return Precision::kFp32;
  if (requested == "auto") return cpu.avx512_bf16 ? Precision::kBf16 : Precision::kFp32;
  if (requested == "bf16") {
    if (!cpu.avx512_bf16) {
      throw std::invalid_argument(
          "precision bf16 needs a CPU with AVX512-BF16 (vdpbf16ps: AMD Zen 4 or later, Intel Cooper Lake, "
          "Sapphire Rapids or later), and this one does not have it (bf16 is not emulated): use precision "
          "fp32 or auto");
    }
    return Precision::kBf16;
  }
  throw std::invalid_argument("precision '" + std::string(requested) + "' is not one of fp32, bf16, auto");
}

std::string precision_description(Precision p) {
  if (p == Precision::kBf16) return "bf16 (bf16 operands, float accumulation: AVX512-BF16 vdpbf16ps)";
  return "fp32 (" + kernels::isa_description() + ")";
}

}  // namespace hns::nn
