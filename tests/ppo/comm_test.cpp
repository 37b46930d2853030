// The trainer over several ranks without MPI: ranks as threads of this process, joined by a Comm over shared
// memory with the same contract as the MPI one (gathers in rank order, the gradient folded rank after rank).
// So the rank logic (blocks, per-block sums, the chain, the sliced action stream) is tested in every build,
// the sanitizer builds (which have no MPI) included: 2 and 3 ranks end in the state of one process.
#include "ppo/comm.hpp"
#include "nn/kernels.hpp"
#include "ppo/arithmetic.hpp"
#include "ppo/trainer.hpp"

#include <gtest/gtest.h>

#include <barrier>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

namespace hns::ppo {
namespace {

// What the ranks of one group share.
struct Group {
  explicit Group(int n) : size(n), sync(n), slots(size_t(n)), ints(size_t(n)), outs(size_t(n)) {}
  int size;
  std::barrier<> sync;
  std::vector<std::vector<double>> slots;
  std::vector<int64_t> ints;
  std::vector<float*> outs;  // each rank's chain_sum output
  std::mutex m;
  std::condition_variable turn_changed;
  int turn = 0;  // the rank whose fold is next
};

class ThreadComm final : public Comm {
 public:
  ThreadComm(Group& g, int rank) : g_(g), rank_(rank) {}
  int rank() const override { return rank_; }
  int size() const override { return g_.size; }
  void allgather(std::span<const double> mine, std::vector<double>& all) override {
    g_.slots[size_t(rank_)].assign(mine.begin(), mine.end());
    g_.sync.arrive_and_wait();
    all.clear();
    for (const std::vector<double>& s : g_.slots) all.insert(all.end(), s.begin(), s.end());
    g_.sync.arrive_and_wait();
  }
  int64_t sum(int64_t mine) override {
    g_.ints[size_t(rank_)] = mine;
    g_.sync.arrive_and_wait();
    int64_t total = 0;
    for (int64_t v : g_.ints) total += v;
    g_.sync.arrive_and_wait();
    return total;
  }
  bool any(bool mine) override { return sum(mine ? 1 : 0) > 0; }
  void chain_sum(size_t n, const Fold& fold, float* out) override {
    g_.outs[size_t(rank_)] = out;
    {
      std::unique_lock<std::mutex> lock(g_.m);
      g_.turn_changed.wait(lock, [&] { return g_.turn == rank_; });
    }
    fold(0, n, rank_ > 0 ? g_.outs[size_t(rank_ - 1)] : nullptr, out);
    {
      std::lock_guard<std::mutex> lock(g_.m);
      g_.turn = rank_ + 1;
    }
    g_.turn_changed.notify_all();
    g_.sync.arrive_and_wait();  // the last rank's sum is complete
    if (rank_ + 1 < g_.size) std::copy_n(g_.outs[size_t(g_.size - 1)], n, out);
    g_.sync.arrive_and_wait();
    if (rank_ == 0) g_.turn = 0;
    g_.sync.arrive_and_wait();
  }
  double take_seconds() override { return 0.0; }
  int ranks_on_this_machine() override { return g_.size; }

 private:
  Group& g_;
  int rank_;
};

// Two quadrant iterations of a small run with 3 update blocks (6 envs; 4-agent rows and their chunks).
TrainConfig three_blocks(const std::string& scene) {
  TrainConfig c;
  c.scene = scene;
  c.model = "small";
  c.envs = 6;
  c.horizon = scene == "full" ? 30 : 40;
  c.epochs = 2;
  c.minibatches = scene == "full" ? 1 : 2;
  c.grad_groups = 3;
  c.threads = 1;
  c.seed = 17;
  return c;
}

// The fingerprint (every byte a checkpoint holds) of every rank after `iterations`, ranks as threads.
std::vector<uint64_t> run_ranks(const TrainConfig& c, int ranks, int iterations) {
  Group g(ranks);
  std::vector<uint64_t> prints(static_cast<size_t>(ranks), 0);
  std::vector<std::string> errors(static_cast<size_t>(ranks));
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r) {
    threads.emplace_back([&, r] {
      try {
        ThreadComm comm(g, r);
        Trainer t(c, &comm);
        for (int i = 0; i < iterations; ++i) t.iterate();
        prints[size_t(r)] = t.fingerprint();
      } catch (const std::exception& e) {
        errors[size_t(r)] = e.what();
      }
    });
  }
  for (std::thread& t : threads) t.join();
  for (int r = 0; r < ranks; ++r) EXPECT_EQ(errors[size_t(r)], "") << "rank " << r;
  return prints;
}

TEST(Comm, RanksAsThreadsEndInTheStateOfOneProcess) {
  for (const std::string scene : {"quadrant", "full"}) {
    const TrainConfig c = three_blocks(scene);
    ASSERT_EQ(c.update_blocks(), 3) << scene;
    Trainer single(c);
    for (int i = 0; i < 2; ++i) single.iterate();
    const uint64_t one = single.fingerprint();
    for (int ranks : {2, 3}) {
      const std::vector<uint64_t> prints = run_ranks(c, ranks, 2);
      for (int r = 0; r < ranks; ++r)
        EXPECT_EQ(prints[size_t(r)], one) << scene << ", rank " << r << " of " << ranks;
    }
  }
}

TEST(Comm, MoreRanksThanBlocksIsRefused) {
  TrainConfig c = three_blocks("quadrant");
  Group g(4);
  ThreadComm comm(g, 0);
  EXPECT_THROW(Trainer(c, &comm), physics::ConfigError);
}

// Each rank's error from check_same_arithmetic with these descriptions ("" where it passed).
std::vector<std::string> check_arithmetics(const std::vector<std::string>& mine) {
  const int ranks = static_cast<int>(mine.size());
  Group g(ranks);
  std::vector<std::string> errors(static_cast<size_t>(ranks));
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r) {
    threads.emplace_back([&, r] {
      ThreadComm comm(g, r);
      try {
        check_same_arithmetic(comm, mine[size_t(r)]);
      } catch (const physics::ConfigError& e) {
        errors[size_t(r)] = e.what();
      }
    });
  }
  for (std::thread& t : threads) t.join();
  return errors;
}

// Ranks that resolve auto differently, or run bf16 on different kernels, or come from different builds,
// would train with different roundings (a result that depends on which machine holds which rank): every
// rank stops with one message naming the first rank that differs and both arithmetics.
TEST(Comm, RanksThatComputeDifferentlyAreRefusedByName) {
  const std::string here = arithmetic_description(nn::Precision::kFp32);
  EXPECT_EQ(here, "fp32 on the " + nn::kernels::isa_description() + " build");
  for (const std::string& e : check_arithmetics({here, here, here})) EXPECT_EQ(e, "");
  const std::string fp32 = "fp32 on the avx512 (AVX-512, 16 floats per vector, FMA) build";
  const std::string no_fma = "fp32 on the avx2 (AVX2, 8 floats per vector) build";
  const std::string amx = "bf16 on the amx kernel, avx512 (AVX-512, 16 floats per vector, FMA) build";
  const std::string dp = "bf16 on the avx512-bf16 kernel, avx512 (AVX-512, 16 floats per vector, FMA) build";
  for (const auto& [ranks, bad] : std::vector<std::pair<std::vector<std::string>, int>>{
           {{dp, dp, amx}, 2}, {{amx, dp}, 1}, {{dp, fp32, fp32}, 1}, {{fp32, no_fma}, 1}}) {
    const std::vector<std::string> errors = check_arithmetics(ranks);
    for (size_t r = 0; r < ranks.size(); ++r) {
      const std::string& e = errors[r];
      EXPECT_NE(e.find("rank " + std::to_string(bad) + " computes in " + ranks[size_t(bad)] +
                       " and rank 0 in " + ranks[0]),
                std::string::npos)
          << "rank " << r << ": " << e;
      EXPECT_NE(e.find("HNS_BF16_KERNEL=avx512-bf16"), std::string::npos) << e;
    }
  }
  // A rank of a build from before the check gathers something else first (check_same_start's checksum):
  // the others refuse it as another build instead of reading it as characters.
  Group g(2);
  std::string error;
  std::thread old_build([&] {
    ThreadComm comm(g, 1);
    std::vector<double> all;
    comm.allgather(std::vector<double>{3.0e9, 7.0}, all);
  });
  {
    ThreadComm comm(g, 0);
    try {
      check_same_arithmetic(comm, here);
    } catch (const physics::ConfigError& e) {
      error = e.what();
    }
  }
  old_build.join();
  EXPECT_NE(error.find("the ranks run different hns builds"), std::string::npos) << error;
  // One process has nothing to compare.
  SingleProcess one;
  EXPECT_NO_THROW(check_same_arithmetic(one, fp32));
}

}  // namespace
}  // namespace hns::ppo
