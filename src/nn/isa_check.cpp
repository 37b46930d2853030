// The start-up check that this CPU has every instruction set extension the build was compiled for. CMake
// compiles this file alone for baseline x86-64 (no AVX of any kind): it runs as a constructor, before main
// and before other static initialisers, so it must not use what it checks. It writes its message with
// write(2) and ends the process with _exit(2): nothing that could be compiled with the build's ISA runs.
#include "nn/isa_features.hpp"

#include <unistd.h>

#include <cstring>

#ifndef HNS_ISA_SETTING
#define HNS_ISA_SETTING "unknown"
#endif

namespace hns::nn::kernels {

const char* isa_first_missing() {
  __builtin_cpu_init();
  // One literal per feature (__builtin_cpu_supports takes nothing else).
#define HNS_CHECK(bit, name) \
  if ((kIsaCompiled & (bit)) != 0 && __builtin_cpu_supports(name) == 0) return name
  HNS_CHECK(kIsaAvx2, "avx2");
  HNS_CHECK(kIsaFma, "fma");
  HNS_CHECK(kIsaBmi, "bmi");
  HNS_CHECK(kIsaBmi2, "bmi2");
#if !defined(__clang__)  // clang 14 knows neither name (every AVX2 CPU has F16C)
  HNS_CHECK(kIsaF16c, "f16c");
#endif
  HNS_CHECK(kIsaAvx512f, "avx512f");
  HNS_CHECK(kIsaAvx512bw, "avx512bw");
  HNS_CHECK(kIsaAvx512cd, "avx512cd");
  HNS_CHECK(kIsaAvx512dq, "avx512dq");
  HNS_CHECK(kIsaAvx512vl, "avx512vl");
  HNS_CHECK(kIsaAvx512vnni, "avx512vnni");
  HNS_CHECK(kIsaAvx512bf16, "avx512bf16");
  HNS_CHECK(kIsaAvx512ifma, "avx512ifma");
  HNS_CHECK(kIsaAvx512vbmi, "avx512vbmi");
  HNS_CHECK(kIsaAvx512vbmi2, "avx512vbmi2");
  HNS_CHECK(kIsaAvx512bitalg, "avx512bitalg");
  HNS_CHECK(kIsaAvx512vpopcntdq, "avx512vpopcntdq");
  HNS_CHECK(kIsaGfni, "gfni");
#if !defined(__clang__)  // clang 14 knows neither name
  HNS_CHECK(kIsaVaes, "vaes");
  HNS_CHECK(kIsaVpclmulqdq, "vpclmulqdq");
  HNS_CHECK(kIsaAvx512vp2intersect, "avx512vp2intersect");
#endif
#undef HNS_CHECK
  return nullptr;
}

namespace {

void put(const char* s) {
  const ssize_t ignored = write(2, s, std::strlen(s));
  (void)ignored;
}

__attribute__((constructor(101))) void check_isa_at_start() {
  const char* missing = isa_first_missing();
  if (missing == nullptr) return;
  put("hns: this build uses ");
  put(missing);
  put(" (HNS_ISA=" HNS_ISA_SETTING
      "), which this CPU does not have: rebuild with HNS_ISA=avx2 tools/run (or "
      "cmake -DHNS_ISA=avx2)\n");
  _exit(2);
}

}  // namespace
}  // namespace hns::nn::kernels
