#include "physics/ode_runtime.hpp"

#include <ode/ode.h>

#include <mutex>

namespace hns::physics {
namespace {
thread_local Rng* t_solver_rng = nullptr;
thread_local Rng t_fallback_rng(0x5EED, 0, 0);
thread_local unsigned long long t_solver_calls = 0;
thread_local bool t_thread_ready = false;
std::once_flag g_ode_init;
}  // namespace

void ensure_ode_thread() {
  if (t_thread_ready) return;
  std::call_once(g_ode_init, [] { dInitODE2(0); });
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
