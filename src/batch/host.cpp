#include "batch/host.hpp"

#include <tbb/info.h>
#include <unistd.h>

#include <algorithm>
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

void check_memory(const std::string& what, size_t bytes) {
  const size_t available = available_memory_bytes();
  if (available > 0 && bytes > available) {
    char buf[256];
    std::snprintf(buf, sizeof buf, "%s needs about %.1f GB of memory, this machine has %.1f GB available",
                  what.c_str(), double(bytes) / (1 << 30), double(available) / (1 << 30));
    throw physics::ConfigError(buf);
  }
}

}  // namespace hns::batch
