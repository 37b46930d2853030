// The processes that train one run together (data parallelism across processes, e.g. MPI ranks): what the
// trainer needs from them, as collective operations every rank calls in the same order. The trainer splits
// its envs into update blocks (TrainConfig::update_blocks()); rank r of R owns blocks [K r / R, K (r + 1) /
// R) and only their envs, data and gradient groups. Every operation here is defined over blocks or ranks in a
// fixed order, so that what the trainer computes does not depend on how many ranks there are (never "what
// MPI_Allreduce happens to do").
//
// SingleProcess is the whole run in this process; the MPI implementation lives in its own library
// (hns_mpi, src/ppo/mpi_comm.hpp), linked by the command line only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

namespace hns::ppo {

class Comm {
 public:
  virtual ~Comm() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  // Every rank's `mine` (any length, possibly different per rank) concatenated in rank order into `all`.
  virtual void allgather(std::span<const double> mine, std::vector<double>& all) = 0;
  // Sum over ranks of one integer per rank (exact).
  virtual int64_t sum(int64_t mine) = 0;
  // Logical or over ranks (a stop request seen by any rank stops every rank at the same iteration).
  virtual bool any(bool mine) = 0;
  // The gradient's chain sum over n floats: the ranks in rank order each fold their own terms onto the sum of
  // the ranks before them: fold(begin, end, before, out) writes out[i] for i in [begin, end): the sum of
  // every term up to this rank's, starting from before[i - begin] (the earlier ranks' sum; null on rank 0).
  // Called for consecutive slices of [0, n); at the end `out` holds the whole sum on every rank.
  using Fold = std::function<void(size_t begin, size_t end, const float* before, float* out)>;
  virtual void chain_sum(size_t n, const Fold& fold, float* out) = 0;
  // Seconds spent inside these operations since the last call, waiting for slower ranks included (the time
  // split's "communication").
  virtual double take_seconds() = 0;
  // Ranks on this machine, this one included (they share its memory).
  virtual int ranks_on_this_machine() = 0;
};

// One process holds the whole run.
class SingleProcess final : public Comm {
 public:
  int rank() const override { return 0; }
  int size() const override { return 1; }
  void allgather(std::span<const double> mine, std::vector<double>& all) override {
    all.assign(mine.begin(), mine.end());
  }
  int64_t sum(int64_t mine) override { return mine; }
  bool any(bool mine) override { return mine; }
  void chain_sum(size_t n, const Fold& fold, float* out) override { fold(0, n, nullptr, out); }
  double take_seconds() override { return 0.0; }
  int ranks_on_this_machine() override { return 1; }
};

}  // namespace hns::ppo
