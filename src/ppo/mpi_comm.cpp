#include "ppo/mpi_comm.hpp"

#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <stdexcept>

namespace hns::ppo {
namespace {

using Clock = std::chrono::steady_clock;

// Floats per message of the gradient chain: small enough to pipeline through the ranks, large enough that a
// message's latency does not matter (1 MiB).
constexpr size_t kChainSlice = size_t(1) << 18;

void check(int rc, const char* what) {
  if (rc == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int len = 0;
  MPI_Error_string(rc, text, &len);
  throw std::runtime_error(std::string("MPI ") + what + " failed: " + std::string(text, size_t(len)));
}

// Adds the time of one collective operation to `seconds` when it goes out of scope.
struct Timed {
  double& seconds;
  Clock::time_point t0 = Clock::now();
  ~Timed() { seconds += std::chrono::duration<double>(Clock::now() - t0).count(); }
};

}  // namespace

bool launched_by_mpi() {
  for (const char* var : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
    if (std::getenv(var) != nullptr) return true;
  return false;
}

MpiComm::MpiComm() {
  int provided = 0;
  check(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
  if (provided < MPI_THREAD_FUNNELED) {
    MPI_Finalize();
    throw std::runtime_error(
        "the MPI library does not support MPI_THREAD_FUNNELED (hns's TBB threads never call "
        "MPI, but the library must allow them)");
  }
  // Errors come back as return codes (checked below) instead of ending the job inside MPI.
  check(MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN), "MPI_Comm_set_errhandler");
  check(MPI_Comm_rank(MPI_COMM_WORLD, &rank_), "MPI_Comm_rank");
  check(MPI_Comm_size(MPI_COMM_WORLD, &size_), "MPI_Comm_size");
}

MpiComm::~MpiComm() {
  MPI_Finalize();
}

void MpiComm::allgather(std::span<const double> mine, std::vector<double>& all) {
  Timed timed{seconds_};
  const int count = int(mine.size());
  std::vector<int> counts(static_cast<size_t>(size_), 0), offsets(static_cast<size_t>(size_), 0);
  check(MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD), "MPI_Allgather");
  int total = 0;
  for (int r = 0; r < size_; ++r) {
    offsets[size_t(r)] = total;
    total += counts[size_t(r)];
  }
  all.resize(size_t(total));
  check(MPI_Allgatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), offsets.data(), MPI_DOUBLE,
                       MPI_COMM_WORLD),
        "MPI_Allgatherv");
}

int64_t MpiComm::sum(int64_t mine) {
  Timed timed{seconds_};
  long long in = mine, out = 0;
  check(MPI_Allreduce(&in, &out, 1, MPI_LONG_LONG, MPI_SUM, MPI_COMM_WORLD), "MPI_Allreduce");
  return int64_t(out);
}

bool MpiComm::any(bool mine) {
  Timed timed{seconds_};
  int in = mine ? 1 : 0, out = 0;
  check(MPI_Allreduce(&in, &out, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD), "MPI_Allreduce");
  return out != 0;
}

void MpiComm::chain_sum(size_t n, const Fold& fold, float* out) {
  Timed timed{seconds_};
  before_.resize(std::min(n, kChainSlice));
  for (size_t begin = 0; begin < n; begin += kChainSlice) {
    const size_t end = std::min(n, begin + kChainSlice);
    const int len = int(end - begin);
    if (rank_ > 0) {
      check(MPI_Recv(before_.data(), len, MPI_FLOAT, rank_ - 1, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE),
            "MPI_Recv");
    }
    fold(begin, end, rank_ > 0 ? before_.data() : nullptr, out);
    if (rank_ + 1 < size_) {
      check(MPI_Send(out + begin, len, MPI_FLOAT, rank_ + 1, 0, MPI_COMM_WORLD), "MPI_Send");
    }
  }
  // The last rank holds the whole sum.
  for (size_t begin = 0; begin < n; begin += size_t(1) << 28) {
    const int len = int(std::min(n - begin, size_t(1) << 28));
    check(MPI_Bcast(out + begin, len, MPI_FLOAT, size_ - 1, MPI_COMM_WORLD), "MPI_Bcast");
  }
}

int MpiComm::ranks_on_this_machine() {
  MPI_Comm node;
  check(MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank_, MPI_INFO_NULL, &node),
        "MPI_Comm_split_type");
  int n = 1;
  MPI_Comm_size(node, &n);
  MPI_Comm_free(&node);
  return n;
}

double MpiComm::take_seconds() {
  const double s = seconds_;
  seconds_ = 0;
  return s;
}

void MpiComm::abort(int status) {
  MPI_Abort(MPI_COMM_WORLD, status);
  std::exit(status);
}

std::string MpiComm::library_version() {
  char text[MPI_MAX_LIBRARY_VERSION_STRING];
  int len = 0;
  MPI_Get_library_version(text, &len);
  std::string v(text, size_t(len));
  const size_t nl = v.find_first_of("\n,");
  return nl == std::string::npos ? v : v.substr(0, nl);
}

}  // namespace hns::ppo
