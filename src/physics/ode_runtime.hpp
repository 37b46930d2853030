// Process- and thread-level ODE set-up, and the per-world random stream behind ODE's solver.
//
// ODE's QuickStep shuffles its constraint rows with the global dRandInt(), whose single seed is shared by
// every world and thread: the result would depend on how worlds interleave. hns defines dRandInt itself
// (ELF interposition over libode.so) and draws from the stream of the world being stepped on this thread,
// so a world's trajectory depends only on its own seed.
#pragma once

#include "physics/rng.hpp"

namespace hns::physics {

// dInitODE2 once per process and dAllocateODEDataForThread once per calling thread. Cheap after the first
// call on a thread; call it before touching ODE on any thread (TBB workers included).
void ensure_ode_thread();

// While alive, ODE's dRandInt() on this thread draws from `rng`.
class ScopedSolverRng {
 public:
  explicit ScopedSolverRng(Rng& rng);
  ~ScopedSolverRng();
  ScopedSolverRng(const ScopedSolverRng&) = delete;
  ScopedSolverRng& operator=(const ScopedSolverRng&) = delete;

 private:
  Rng* previous_;
};

// How many dRandInt() calls this thread served (tests use it to prove the interposition is live).
unsigned long long solver_rng_calls();

}  // namespace hns::physics
