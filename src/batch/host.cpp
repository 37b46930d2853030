#include "batch/host.hpp"

#include <sys/resource.h>
#include <tbb/info.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <fstream>

#include "physics/scene.hpp"

namespace hns::batch {

int usable_threads(int requested) {
  const int hardware = tbb::info::default_concurrency();
  return requested <= 0 ? hardware : std::min(requested, hardware);
}

size_t available_memory_bytes() {
  std::ifstream meminfo("/proc/meminfo");
  std::string key;
  size_t kb = 0;
  size_t available = 0;
  while (meminfo >> key >> kb) {
    if (key == "MemAvailable:") available = kb * 1024;
    meminfo.ignore(64, '\n');
  }
  if (available == 0) available = size_t(::sysconf(_SC_AVPHYS_PAGES)) * size_t(::sysconf(_SC_PAGESIZE));
  return available;
}

size_t address_space_left_bytes() {
  rlimit lim{};
  if (::getrlimit(RLIMIT_AS, &lim) != 0 || lim.rlim_cur == RLIM_INFINITY) return SIZE_MAX;
  // The process's present virtual size (statm's first field, in pages).
  std::ifstream statm("/proc/self/statm");
  size_t pages = 0;
  statm >> pages;
  const size_t used = pages * size_t(::sysconf(_SC_PAGESIZE));
  return size_t(lim.rlim_cur) > used ? size_t(lim.rlim_cur) - used : 0;
}

void check_memory(const std::string& what, size_t bytes) {
  char buf[320];
  // The process's own limit first, so that a run it refuses says so whatever memory the machine has free.
  const size_t as_left = address_space_left_bytes();
  if (bytes > as_left) {
    std::snprintf(buf, sizeof buf,
                  "%s needs about %.1f GB of memory, and this process's address-space limit (ulimit -v) "
                  "leaves %.1f GB",
                  what.c_str(), double(bytes) / (1 << 30), double(as_left) / (1 << 30));
    throw physics::ConfigError(buf);
  }
  const size_t available = available_memory_bytes();
  if (available > 0 && bytes > available) {
    std::snprintf(buf, sizeof buf, "%s needs about %.1f GB of memory, this machine has %.1f GB available",
                  what.c_str(), double(bytes) / (1 << 30), double(available) / (1 << 30));
    throw physics::ConfigError(buf);
  }
}

}  // namespace hns::batch
