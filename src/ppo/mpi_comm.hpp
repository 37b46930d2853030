// ppo::Comm over MPI (library hns_mpi, built when CMake finds MPI; linked by the command line only, so the
// simulator, the networks and the Python module know nothing of it).
//
// Every float operation is built from point-to-point messages and gathers in a fixed order, never from MPI's
// own reductions (whose summation order depends on the algorithm and the topology): allgather concatenates in
// rank order; sum() and any() reduce integers with MPI_Allreduce (exact in any order); chain_sum passes the
// running gradient sum from rank to rank in slices (rank r receives the sum of ranks < r for a slice, folds
// its own blocks onto it and sends it on; slices pipeline through the chain), then the last rank broadcasts
// the result. So a run gives the same bits on 1, 2 or 4 ranks.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "ppo/comm.hpp"

namespace hns::ppo {

// True when this process was started by an MPI launcher (mpirun / mpiexec / srun with PMI or PMIx), i.e. when
// MpiComm should be used.
bool launched_by_mpi();

class MpiComm final : public Comm {
 public:
  // MPI_Init_thread (funneled: only the thread that made this object calls MPI); errors return to the caller
  // as exceptions. MPI_Finalize in the destructor.
  MpiComm();
  ~MpiComm() override;
  MpiComm(const MpiComm&) = delete;
  MpiComm& operator=(const MpiComm&) = delete;

  int rank() const override { return rank_; }
  int size() const override { return size_; }
  void allgather(std::span<const double> mine, std::vector<double>& all) override;
  int64_t sum(int64_t mine) override;
  bool any(bool mine) override;
  void chain_sum(size_t n, const Fold& fold, float* out) override;
  double take_seconds() override;
  int ranks_on_this_machine() override;

  // Ends every rank of the job at once (MPI_Abort) with this exit status: for a rank that cannot go on while
  // the others wait for it.
  [[noreturn]] void abort(int status);
  // The MPI library's version string (for the start-up line).
  static std::string library_version();

 private:
  int rank_ = 0;
  int size_ = 1;
  double seconds_ = 0;
  std::vector<float> before_;  // a slice of the running sum from the previous rank
};

}  // namespace hns::ppo
