// hns train's run folder (train_folder.hpp).
#include "train_folder.hpp"

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "cli.hpp"
#include "physics/scene.hpp"
#include "ppo/trainer.hpp"
#include "replay/metrics.hpp"

namespace hns::tools {

namespace fs = std::filesystem;

std::string truncate_metrics(const std::string& path, int64_t iteration) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return "";
  std::string text;
  try {
    text = ppo::read_regular_file(path, ppo::kMaxMetricsBytes, "--resume:");
  } catch (const std::exception& e) {
    throw physics::ConfigError(e.what());
  }
  std::string kept;
  std::istringstream in(text);
  std::string line;
  std::vector<std::string> dropped;
  for (int64_t number = 1; std::getline(in, line); ++number) {
    // Only rows hns report reads (replay::is_iteration_record) are kept.
    if (!replay::is_iteration_record(line)) {
      if (!line.empty()) dropped.push_back(std::to_string(number));
      continue;
    }
    const nlohmann::json row = nlohmann::json::parse(line);
    if (row["iteration"].get<int64_t>() > iteration) continue;
    kept += line + "\n";
  }
  if (!dropped.empty()) {
    std::string lines;
    for (const std::string& n : dropped) lines += (lines.empty() ? "" : ", ") + n;
    std::fprintf(
        stderr,
        "hns train: warning: %s: line%s %s %s not a whole metrics row (torn by a crash or damaged) and "
        "%s dropped; every other row up to iteration %lld is kept\n",
        path.c_str(), dropped.size() > 1 ? "s" : "", lines.c_str(), dropped.size() > 1 ? "are" : "is",
        dropped.size() > 1 ? "were" : "was", static_cast<long long>(iteration));
  }
  write_atomically(path, kept);
  return kept;
}

void check_run_folder(const std::string& dir) {
  std::error_code ec;
  if (!fs::exists(dir, ec)) return;
  if (!fs::is_directory(dir, ec)) throw physics::ConfigError("--out " + dir + " exists and is not a folder");
  if (fs::exists(fs::path(dir) / kRunMarker, ec)) return;
  fs::directory_iterator it(dir, ec);
  if (ec) throw physics::ConfigError("--out " + dir + " cannot be read: " + ec.message());
  // Empty, but for the lock file a refused start may have left (it marks nothing: any hns train creates it).
  while (it != fs::directory_iterator() && it->path().filename() == ppo::FolderLock::kFileName)
    it.increment(ec);
  if (it == fs::directory_iterator()) return;
  // A run from before the marker: a whole, valid checkpoint (its checksum checked), not 8 bytes of magic.
  const std::string ckpt = (fs::path(dir) / "checkpoint.bin").string();
  if (fs::is_regular_file(ckpt, ec)) {
    try {
      (void)ppo::Trainer::checkpoint_config(ckpt);
      return;
    } catch (const std::exception&) {
      // not a checkpoint of hns: the folder is not a run folder
    }
  }
  throw physics::ConfigError("--out " + dir + " holds '" + it->path().filename().string() +
                             "' and is not a run folder of hns train: give a new or empty folder (hns never "
                             "removes files it did not write, --overwrite included)");
}

void check_no_run_unless(bool overwrite, const std::string& dir, const std::string& ckpt) {
  std::error_code ec;
  if (fs::exists(ckpt, ec) && !overwrite) {
    throw physics::ConfigError("--out " + dir + " already holds a run: continue it with --resume " + dir +
                               ", or start over with --overwrite");
  }
}

ppo::FolderLock lock_run_folder(const std::string& flag, const std::string& dir) {
  try {
    ppo::FolderLock lock(dir);
    if (!lock.warning().empty()) std::fprintf(stderr, "hns train: warning: %s\n", lock.warning().c_str());
    return lock;
  } catch (const std::runtime_error& e) {
    throw physics::ConfigError(flag + " " + e.what());
  }
}

}  // namespace hns::tools
