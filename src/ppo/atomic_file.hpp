// Files hns writes and reads: atomic writes that follow no planted link and replace no special file, bounded
// reads of regular files only, and the FNV-1a 64 checksum.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
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

// A file that hns refuses to read or replace: not a regular file, or larger than its format allows.
struct FileError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// What a file that is not a regular file is, for messages: "a FIFO", "a character device", "a folder", ...
// Empty for a regular file.
std::string special_file_kind(unsigned mode);

// Writing a file so that readers see either the old file or the whole new one, never a part: the bytes go
// to PATH.tmp, are flushed to the disk (fsync), then renamed over PATH. On any failure PATH is unchanged,
// PATH.tmp is removed and std::runtime_error names the file and the reason. An existing PATH that is not a
// regular file (a device, a FIFO: renaming over it would replace it) is refused with FileError, and a link or
// file left as PATH.tmp is removed, never written through (create_temp_file).
void write_file_atomically(const std::string& path, std::string_view bytes);

// Creates `tmp` for writing: whatever is there (a stale temporary, or a link planted to redirect the write)
// is removed first (the link itself, not its target), then the file is created exclusively without following
// links (O_EXCL | O_NOFOLLOW). Returns the descriptor; throws std::runtime_error naming `tmp`.
int create_temp_file(const std::string& tmp);

// Throws FileError when `path` exists and, links followed, is not a regular file: a writer that renames its
// output over `path` would replace a device or a FIFO with a regular file. `what` names the path in the
// message (a flag such as "--out", or a description).
void check_replaceable(const std::string& path, std::string_view what);

// The whole of the regular file `path`, at most `max_bytes` long. Anything else is refused with FileError
// before a byte is read: a FIFO (the open does not wait for a writer), a device (/dev/zero never ends), a
// socket, a folder, and a file larger than `max_bytes` (by its size; one that grows while it is read is
// refused too). `what` names the file in messages ("checkpoint", "--config"); a file that cannot be opened
// or read throws std::system_error ("cannot open checkpoint PATH: No such file or directory", its code the
// errno).
std::string read_regular_file(const std::string& path, uint64_t max_bytes, std::string_view what);

// An exclusive claim on a folder for as long as this object lives: an advisory lock (flock) on
// FOLDER/.hns-lock, which records the holder's process id and command line. The system drops the lock when
// the process ends however it ends (kill -9 included), so a crashed run never leaves its folder locked. Two
// processes on one machine exclude each other; on a network file system that is true only where the server
// supports flock (NFSv4 does; some others give each client its own lock).
class FolderLock {
 public:
  static constexpr const char* kFileName = ".hns-lock";
  FolderLock() = default;
  // Takes the lock; throws FileError "FOLDER is in use by process PID (COMMAND LINE)" when another process
  // holds it, std::runtime_error when the lock file cannot be created. Where the file system has no flock
  // (ENOLCK, EOPNOTSUPP, ENOSYS: some network file systems) the folder goes unlocked and warning() says so.
  explicit FolderLock(const std::string& folder);
  FolderLock(FolderLock&& other) noexcept : fd_(other.fd_), warning_(std::move(other.warning_)) {
    other.fd_ = -1;
  }
  FolderLock& operator=(FolderLock&& other) noexcept;
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;
  ~FolderLock();
  bool held() const { return fd_ >= 0 || !warning_.empty(); }
  const std::string& warning() const { return warning_; }

 private:
  int fd_ = -1;
  std::string warning_;
};

// Size limits of hns's files, far above anything hns writes and far below what would exhaust a machine.
inline constexpr uint64_t kMaxConfigBytes = uint64_t(1) << 20;       // config.json, --config
inline constexpr uint64_t kMaxCheckpointBytes = uint64_t(4) << 30;   // checkpoint.bin
inline constexpr uint64_t kMaxMetricsBytes = uint64_t(4) << 30;      // metrics.jsonl
inline constexpr uint64_t kMaxTrajectoryBytes = uint64_t(16) << 30;  // .traj recordings

}  // namespace hns::ppo
