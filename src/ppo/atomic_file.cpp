#include "ppo/atomic_file.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>

namespace hns::ppo {

std::string special_file_kind(unsigned mode) {
  if (S_ISREG(mode)) return "";
  if (S_ISDIR(mode)) return "a folder";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a plain file";
}

int create_temp_file(const std::string& tmp) {
  if (::unlink(tmp.c_str()) != 0 && errno != ENOENT && errno != EISDIR && errno != EPERM)
    throw std::runtime_error("cannot remove the stale " + tmp + ": " + std::strerror(errno));
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0) throw std::runtime_error("cannot write " + tmp + ": " + std::strerror(errno));
  return fd;
}

void check_replaceable(const std::string& path, std::string_view what) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return;  // absent (or unreachable: the write will say why)
  const std::string kind = special_file_kind(st.st_mode);
  if (!kind.empty()) {
    throw FileError(std::string(what) + (what.empty() ? "" : " ") + path + " is not a regular file (" + kind +
                    "): hns writes its outputs by replacing the file, and replaces only regular files");
  }
}

std::string read_regular_file(const std::string& path, uint64_t max_bytes, std::string_view what) {
  const std::string name = std::string(what) + (what.empty() ? "" : " ") + path;
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer, forever.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  const auto system_error = [&](const char* verb) {
    return std::system_error(errno, std::generic_category(), std::string(verb) + " " + name);
  };
  if (fd < 0) throw system_error("cannot open");
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw system_error("cannot read");
  const std::string kind = special_file_kind(st.st_mode);
  if (!kind.empty()) throw FileError(name + " is not a regular file (" + kind + ")");
  const auto too_large = [&] {
    return FileError(name + " is larger than " + std::to_string(max_bytes) +
                     " bytes, the most such a file can be");
  };
  if (uint64_t(st.st_size) > max_bytes) throw too_large();
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  // One byte more than the size, to see the end in the same pass; more only for a file that grows meanwhile.
  std::string bytes(size_t(st.st_size) + 1, '\0');
  size_t done = 0;
  for (;;) {
    if (done == bytes.size()) {
      if (done > max_bytes) throw too_large();
      bytes.resize(std::min<uint64_t>(max_bytes + 1, std::max<uint64_t>(2 * done, 4096)));
    }
    const ssize_t n = ::read(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw system_error("cannot read");
    if (n == 0) break;
    done += size_t(n);
  }
  if (done > max_bytes) throw too_large();
  bytes.resize(done);
  return bytes;
}

void write_file_atomically(const std::string& path, std::string_view bytes) {
  check_replaceable(path, "");
  const std::string tmp = path + ".tmp";
  const auto fail = [&](const std::string& what, int err) {
    std::remove(tmp.c_str());
    throw std::runtime_error("cannot " + what + ": " + std::strerror(err));
  };
  const int fd = create_temp_file(tmp);
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : EIO;
      ::close(fd);
      fail("write " + tmp, err);
    }
    done += size_t(n);
  }
  if (::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    fail("flush " + tmp + " to disk", err);
  }
  if (::close(fd) != 0) fail("close " + tmp, errno);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) fail("rename " + tmp + " to " + path, errno);
}

FolderLock::FolderLock(const std::string& folder) {
  const std::string path = folder + "/" + kFileName;
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0) throw std::runtime_error("cannot create the lock file " + path + ": " + std::strerror(errno));
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    char buf[512] = {};
    const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
    ::close(fd);
    if (err == ENOLCK || err == EOPNOTSUPP || err == ENOSYS) {
      warning_ = "the file system of " + folder + " cannot lock files (" + std::strerror(err) +
                 "): nothing stops a second hns train from writing into it at the same time";
      return;
    }
    if (err != EWOULDBLOCK) throw std::runtime_error("cannot lock " + path + ": " + std::strerror(err));
    std::string holder = n > 0 ? std::string(buf, size_t(n)) : std::string();
    while (!holder.empty() && (holder.back() == '\n' || holder.back() == ' ')) holder.pop_back();
    throw FileError(folder + " is in use by process " + (holder.empty() ? std::string("(unknown)") : holder) +
                    ": wait for it to end, or stop it (Ctrl-C or kill -INT saves its checkpoint) first");
  }
  // Holder: "PID (COMMAND LINE)", read by the process that is refused.
  std::string who = std::to_string(::getpid());
  std::ifstream cmdline("/proc/self/cmdline", std::ios::binary);
  std::string args((std::istreambuf_iterator<char>(cmdline)), std::istreambuf_iterator<char>());
  for (char& c : args) c = c == '\0' ? ' ' : c;
  while (!args.empty() && args.back() == ' ') args.pop_back();
  if (args.size() > 300) args = args.substr(0, 300) + "...";
  if (!args.empty()) who += " (" + args + ")";
  who += "\n";
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, who.data(), who.size(), 0) != ssize_t(who.size())) {
    // The lock holds without the note; the refused process then names no holder.
  }
  fd_ = fd;
}

FolderLock& FolderLock::operator=(FolderLock&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = other.fd_;
    warning_ = std::move(other.warning_);
    other.fd_ = -1;
  }
  return *this;
}

FolderLock::~FolderLock() {
  if (fd_ >= 0) ::close(fd_);
}

}  // namespace hns::ppo
