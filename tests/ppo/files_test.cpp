// The file primitives every reader and writer of hns goes through (src/ppo/atomic_file.hpp): special files
// are refused without being read or replaced, reads are bounded, a planted link is not written through, and a
// folder lock excludes a second holder.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <string>
#include <system_error>

#include <gtest/gtest.h>

#include "ppo/atomic_file.hpp"

namespace hns::ppo {
namespace {

namespace fs = std::filesystem;

class Files : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("hns_files_test_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  static std::string slurp(const std::string& p) {
    std::ifstream in(p);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }
  fs::path dir_;
};

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}

TEST_F(Files, ReadingAFifoIsRefusedAtOnceInsteadOfWaitingForAWriter) {
  ASSERT_EQ(::mkfifo(path("fifo").c_str(), 0600), 0);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_THROW(read_regular_file(path("fifo"), 1000, "checkpoint"), FileError);
  const std::string m = message_of([&] { read_regular_file(path("fifo"), 1000, "checkpoint"); });
  EXPECT_NE(m.find("checkpoint " + path("fifo") + " is not a regular file (a FIFO)"), std::string::npos) << m;
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
}

TEST_F(Files, DevicesAndFoldersAreRefusedWithTheirKind) {
  EXPECT_NE(message_of([] {
              read_regular_file("/dev/zero", 1 << 20, "--config");
            }).find("--config /dev/zero is not a regular file (a character device)"),
            std::string::npos);
  EXPECT_NE(message_of([&] { read_regular_file(dir_.string(), 1 << 20, ""); }).find("(a folder)"),
            std::string::npos);
}

TEST_F(Files, AFileLargerThanItsFormatAllowsIsRefusedByItsSize) {
  { std::ofstream(path("big")) << std::string(5000, 'x'); }
  const std::string m = message_of([&] { read_regular_file(path("big"), 4999, "metrics"); });
  EXPECT_NE(m.find("is larger than 4999 bytes"), std::string::npos) << m;
  EXPECT_EQ(read_regular_file(path("big"), 5000, "metrics").size(), 5000u);
  // A sparse file of 1 TiB is refused by its size without reading it.
  const int fd = ::open(path("sparse").c_str(), O_WRONLY | O_CREAT, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::ftruncate(fd, off_t(1) << 40), 0);
  ::close(fd);
  EXPECT_THROW(read_regular_file(path("sparse"), kMaxTrajectoryBytes, ""), FileError);
}

TEST_F(Files, AMissingFileThrowsTheSystemsReason) {
  try {
    read_regular_file(path("absent"), 10, "checkpoint");
    FAIL() << "no exception";
  } catch (const std::system_error& e) {
    EXPECT_EQ(e.code().value(), ENOENT);
    EXPECT_NE(std::string(e.what()).find("cannot open checkpoint " + path("absent")), std::string::npos);
  }
}

TEST_F(Files, AnAtomicWriteDoesNotFollowALinkPlantedAsItsTemporaryFile) {
  { std::ofstream(path("precious")) << "precious"; }
  fs::create_symlink(path("precious"), path("config.json.tmp"));
  write_file_atomically(path("config.json"), "{}\n");
  EXPECT_EQ(slurp(path("precious")), "precious");
  EXPECT_FALSE(fs::is_symlink(path("config.json")));
  EXPECT_EQ(slurp(path("config.json")), "{}\n");
  EXPECT_FALSE(fs::exists(fs::symlink_status(path("config.json.tmp"))));
}

TEST_F(Files, AnAtomicWriteDoesNotReplaceASpecialFile) {
  ASSERT_EQ(::mkfifo(path("out").c_str(), 0600), 0);
  EXPECT_THROW(write_file_atomically(path("out"), "x"), FileError);
  EXPECT_TRUE(fs::is_fifo(path("out")));
  EXPECT_FALSE(fs::exists(path("out.tmp")));
  EXPECT_THROW(check_replaceable("/dev/null", "--out"), FileError);
  EXPECT_NO_THROW(check_replaceable(path("absent"), "--out"));
}

TEST_F(Files, AFolderLockExcludesASecondHolderUntilTheFirstIsGone) {
  std::optional<FolderLock> first(std::in_place, dir_.string());
  EXPECT_TRUE(first->held());
  const std::string m = message_of([&] { FolderLock second(dir_.string()); });
  EXPECT_NE(m.find(dir_.string() + " is in use by process " + std::to_string(::getpid())), std::string::npos)
      << m;
  first.reset();
  FolderLock third(dir_.string());
  EXPECT_TRUE(third.held());
}

}  // namespace
}  // namespace hns::ppo
