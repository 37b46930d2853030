// What the host machine offers a run: hardware threads and available memory. Used by every front end (the
// command line, the Python module) before it builds a batch.
#pragma once

#include <cstddef>
#include <string>

namespace hns::batch {

// Worker threads a request really gets: the request, or the machine's hardware threads if fewer;
// requested <= 0 means all of them.
int usable_threads(int requested);

// Bytes the machine has available for new work (MemAvailable of /proc/meminfo, else free physical pages).
size_t available_memory_bytes();

// Address space this process may still map under its RLIMIT_AS (ulimit -v); SIZE_MAX without a limit.
size_t address_space_left_bytes();

// Refuses (physics::ConfigError) work whose estimated memory exceeds what the machine has available, or
// what the address-space limit leaves, naming `what` (e.g. "--envs 100000") and both figures.
void check_memory(const std::string& what, size_t bytes);

}  // namespace hns::batch
