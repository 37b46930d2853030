// The instruction set extensions this build was compiled for, as a bit set (defined in kernels.cpp, which is
// compiled with the build's flags), and the start-up check against the CPU (isa_check.cpp, compiled for
// baseline x86-64).
#pragma once

namespace hns::nn::kernels {

enum IsaFeature : unsigned {
  kIsaAvx2 = 1u << 0,
  kIsaFma = 1u << 1,
  kIsaBmi = 1u << 2,
  kIsaBmi2 = 1u << 3,
  kIsaF16c = 1u << 4,
  kIsaAvx512f = 1u << 5,
  kIsaAvx512bw = 1u << 6,
  kIsaAvx512cd = 1u << 7,
  kIsaAvx512dq = 1u << 8,
  kIsaAvx512vl = 1u << 9,
  kIsaAvx512vnni = 1u << 10,
  kIsaAvx512bf16 = 1u << 11,
  kIsaAvx512ifma = 1u << 12,
  kIsaAvx512vbmi = 1u << 13,
  kIsaAvx512vbmi2 = 1u << 14,
  kIsaAvx512bitalg = 1u << 15,
  kIsaAvx512vpopcntdq = 1u << 16,
  kIsaGfni = 1u << 17,
  kIsaVaes = 1u << 18,
  kIsaVpclmulqdq = 1u << 19,
  kIsaAvx512vp2intersect = 1u << 20,
};

// The extensions the build's compiler flags enable (constant data: readable before any constructor).
extern const unsigned kIsaCompiled;

// The first of them this CPU lacks, or null.
const char* isa_first_missing();

}  // namespace hns::nn::kernels
