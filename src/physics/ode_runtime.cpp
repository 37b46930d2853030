#include "physics/ode_runtime.hpp"

#include <ode/ode.h>

#include <cstdio>
#include <cstdlib>

#include <mutex>

namespace hns::physics {
namespace {
thread_local Rng* t_solver_rng = nullptr;
thread_local Rng t_fallback_rng(0x5EED, 0, 0);
thread_local unsigned long long t_solver_calls = 0;
thread_local bool t_thread_ready = false;
std::once_flag g_ode_init;
}  // namespace

namespace {
// ODE has no way to report a failed allocation and would crash on the null pointer: hns ends the process
// with a message and exit status 1 instead (never a signal).
[[noreturn]] void ode_out_of_memory(size_t bytes) {
  std::fprintf(stderr,
               "hns: error: out of memory inside the physics engine (ODE asked for %zu bytes); use fewer "
               "envs or a bigger machine\n",
               bytes);
  std::fflush(stderr);
  std::_Exit(1);
}
void* ode_alloc(dsizeint bytes) {
  void* p = std::malloc(bytes);
  if (p == nullptr && bytes > 0) ode_out_of_memory(bytes);
  return p;
}
void* ode_realloc(void* ptr, dsizeint, dsizeint bytes) {
  void* p = std::realloc(ptr, bytes);
  if (p == nullptr && bytes > 0) ode_out_of_memory(bytes);
  return p;
}
void ode_free(void* ptr, dsizeint) {
  std::free(ptr);
}
}  // namespace

void ensure_ode_thread() {
  if (t_thread_ready) return;
  std::call_once(g_ode_init, [] {
    dSetAllocHandler(ode_alloc);
    dSetReallocHandler(ode_realloc);
    dSetFreeHandler(ode_free);
    dInitODE2(0);
  });
  dAllocateODEDataForThread(dAllocateMaskAll);
  t_thread_ready = true;
}

ScopedSolverRng::ScopedSolverRng(Rng& rng) : previous_(t_solver_rng) {
  t_solver_rng = &rng;
}
ScopedSolverRng::~ScopedSolverRng() {
  t_solver_rng = previous_;
}

unsigned long long solver_rng_calls() {
  return t_solver_calls;
}

}  // namespace hns::physics

// Interposes libode.so's dRandInt (see the header). Returns a uniform integer in [0, n).
extern "C" int dRandInt(int n) {
  using hns::physics::t_fallback_rng;
  using hns::physics::t_solver_rng;
  ++hns::physics::t_solver_calls;
  if (n <= 1) return 0;
  hns::physics::Rng& rng = t_solver_rng != nullptr ? *t_solver_rng : t_fallback_rng;
  return rng.uniform_int(0, n);
}
