// Files the trainer writes and checks: atomic writes, and the FNV-1a 64 checksum.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace hns::ppo {

// FNV-1a 64 of `n` bytes, continuing from `h` (kFnv1a64Basis starts a fresh hash): checkpoint payloads, the
// count-based states' keys, `hns eval`'s checkpoint fingerprints.
inline constexpr uint64_t kFnv1a64Basis = 0xcbf29ce484222325ULL;
inline uint64_t fnv1a64(const void* data, size_t n, uint64_t h = kFnv1a64Basis) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ULL;
  }
  return h;
}

// Writing a file so that readers see either the old file or the whole new one, never a part: the bytes go
// to PATH.tmp, are flushed to the disk (fsync), then renamed over PATH. On any failure PATH is unchanged,
// PATH.tmp is removed and std::runtime_error names the file and the reason.

void write_file_atomically(const std::string& path, std::string_view bytes);

}  // namespace hns::ppo
