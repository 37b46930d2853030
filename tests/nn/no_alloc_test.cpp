// "Nothing allocates in a forward or backward pass once the scratch has grown" (src/nn/README.md "Numerics"):
// this binary counts every operator new, and the C library is told to hand back every block of 128 KB or more
// (so a transient large buffer, from aligned_alloc too, faults on fresh pages). Once a network has run each
// shape, further act() and forward_backward() calls, in both precisions, allocate nothing.
#include "nn/actor_critic.hpp"
#include "nn/bf16_gemm.hpp"
#include "nn/precision.hpp"

#include "net_data.hpp"

#include <gtest/gtest.h>
#include <malloc.h>
#include <oneapi/tbb/global_control.h>
#include <sys/resource.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <span>
#include <vector>

namespace {
std::atomic<long> g_news{0};

void* counted(std::size_t n, std::size_t align) {
  g_news.fetch_add(1, std::memory_order_relaxed);
  n = n == 0 ? 1 : n;
  void* p = align <= alignof(std::max_align_t) ? std::malloc(n)
                                               : std::aligned_alloc(align, (n + align - 1) / align * align);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}
}  // namespace

void* operator new(std::size_t n) {
  return counted(n, 0);
}
void* operator new[](std::size_t n) {
  return counted(n, 0);
}
void* operator new(std::size_t n, std::align_val_t a) {
  return counted(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a) {
  return counted(n, static_cast<std::size_t>(a));
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete[](void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete(void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept {
  std::free(p);
}

namespace hns::nn {
namespace {

long minor_faults() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_minflt;
}

class NnNoAllocation : public ::testing::TestWithParam<Precision> {};

TEST_P(NnNoAllocation, WarmActAndForwardBackwardAllocateNothing) {
  if (GetParam() == Precision::kBf16 && !bf16::available())
    GTEST_SKIP() << "this CPU has no AVX512-BF16: bf16 products cannot run here";
  mallopt(M_MMAP_THRESHOLD, 128 * 1024);
  mallopt(M_TRIM_THRESHOLD, 128 * 1024);
  // One thread: a TBB worker that joins only during the counted calls (under load it may start late) would
  // allocate its own structures and fault in its stack, which is TBB's doing, not the network's (a ctest run
  // of the whole suite saw that once). The networks' code paths are the same at any thread count.
  tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  // The small model at the trainer's shapes: 32 sequences x 10 steps (eight of its 4-sequence training
  // chunks), 64 agents acting.
  const NetConfig cfg = net_preset("small");
  ActorCritic ac(cfg);
  ac.params().init(3);
  ac.set_precision(GetParam());
  const int seqs = 32, steps = 10, rows = seqs * steps, agents = 64;
  const testing::ObsData data(cfg.obs, rows, 11);
  const ObsNormalizer norm = testing::fitted_normalizer(cfg.obs, data, rows);
  const int nl = ac.heads().num_logits(), nh = ac.heads().num_heads(), sw = ac.state_width();
  std::vector<float> grads(ac.params().buffer_floats()), ps(size_t(agents) * sw), vs(ps.size());
  std::vector<float> uniforms(size_t(agents) * nh, 0.5f), logp(agents), value(agents);
  std::vector<int32_t> actions(size_t(agents) * nh);
  std::vector<double> stats(2);
  const LossFn loss = [&](const ChunkOutputs& out, const ChunkGrads& g, std::span<double> st) {
    for (int r = 0; r < out.rows; ++r) {
      for (int k = 0; k < nl; ++k) g.d_logits.at(r, k) = 0.01f * float(k + 1) - out.logits.at(r, k) * 0.001f;
      g.d_value[r] = out.value[r];
    }
    st[0] += out.rows;
  };
  auto run = [&] {
    ac.act(norm.view(), data.batch(), agents, ps.data(), vs.data(), uniforms.data(),
           {actions.data(), logp.data(), value.data(), nullptr});
    ac.forward_backward(norm.view(), data.batch(), seqs, steps, nullptr, nullptr, loss, stats, grads.data());
    ac.params().values()[0] += 1e-3f;  // a new weight version, as after an update (bf16 packs again)
  };
  run();
  run();
  const long news = g_news.load(), faults = minor_faults();
  for (int rep = 0; rep < 3; ++rep) run();
  EXPECT_EQ(g_news.load() - news, 0) << "operator new calls in warm passes";
  EXPECT_LT(minor_faults() - faults, 50) << "page faults in warm passes";
  EXPECT_EQ(stats[0], double(rows));
}

INSTANTIATE_TEST_SUITE_P(Precisions, NnNoAllocation, ::testing::Values(Precision::kFp32, Precision::kBf16),
                         [](const ::testing::TestParamInfo<Precision>& info) {
                           return info.param == Precision::kFp32 ? std::string("fp32") : std::string("bf16");
                         });

}  // namespace
}  // namespace hns::nn
