// The precision of the networks' matrix products, chosen at run time.
//
//   fp32  every product in float (Eigen's GEMM and the packed recurrent kernel): the results of earlier
//         versions, bit for bit.
//   bf16  mixed precision: every matrix product of both networks (dense layers, entity embeddings, the
//         attention projections, the LSTM's input and recurrent products, and the input and weight
//         gradients of all of them) rounds its two operands to bfloat16 (round to nearest even) and
//         accumulates in float, with float results. The weights stay float masters (Adam updates them);
//         their bf16 copies are packed once per weight version (per act() and per minibatch). Layer norms,
//         softmax, the attention core, the LSTM cell, the lidar convolution, the loss, Adam and every
//         reduction stay float. Needs a CPU with a native bf16 dot product (AVX512-BF16: AMD Zen 4 and later,
//         Intel Cooper Lake, Sapphire Rapids and later); it is never emulated. Where the CPU has AMX-BF16
//         tiles (Intel Sapphire Rapids and later) the products run on them, else on vdpbf16ps
//         (bf16::kernel()); the two differ in rounding, so results are bit-identical per kernel.
//   auto  bf16 where the CPU has it, else fp32.
//
// Within one precision and one build (instruction set), results are bit-identical at any thread or rank
// count, as for fp32 (nn/README.md).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace hns::nn {

enum class Precision { kFp32, kBf16 };

// "fp32" / "bf16".
std::string_view precision_name(Precision p);

// What this CPU offers for bf16 products (cpuid, and the operating system's permission for the vector
// state).
struct CpuFeatures {
  bool avx512_bf16 = false;  // vdpbf16ps (AVX512-BF16 with AVX512F/BW/VL)
  bool amx_bf16 = false;     // AMX-BF16 tiles usable (bf16 products then run on them)
  static CpuFeatures detect();
};

// The precision a request means on a CPU: "fp32", "bf16" or "auto". Throws std::invalid_argument with a
// message naming the value and what is allowed, or, for "bf16" on a CPU without a native bf16 dot product,
// saying so (bf16 is not emulated).
Precision resolve_precision(std::string_view requested, const CpuFeatures& cpu = CpuFeatures::detect());
std::vector<std::string> precision_names();  // the accepted requests: fp32, bf16, auto

// What runs the products at precision p on this machine, for start lines and JSON records, e.g.
// "bf16 (bf16 operands, float accumulation: AVX512-BF16 vdpbf16ps)" or "fp32 (avx512 (AVX-512, 16 floats
// per vector, FMA))".
std::string precision_description(Precision p);

}  // namespace hns::nn
