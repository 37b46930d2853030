// hns train's run folder (docs/training.md "The run folder"): which folders may take a run, the lock that
// keeps a second run out, and the metrics rows a resumed run keeps.
#pragma once

#include <cstdint>
#include <string>

#include "ppo/atomic_file.hpp"

namespace hns::tools {

// A run folder is marked by this file, which hns train writes into it; hns train only ever removes its own
// files (checkpoint.bin, metrics.jsonl, replay.traj) from a marked folder and leaves everything else alone.
inline constexpr const char* kRunMarker = ".hns-run";

// Keeps the rows of metrics.jsonl up to `iteration` (a run stopped between writing a row and a checkpoint
// repeats those iterations on resume). Every whole row of an iteration the checkpoint covers is kept; a line
// that is not a complete JSON object with an integer "iteration" (torn by a crash, or damaged) is dropped
// and named on stderr, and the rows after it are kept. Returns the kept text.
std::string truncate_metrics(const std::string& path, int64_t iteration);

// Whether `dir` may take a run: it does not exist, is empty, carries the marker, or holds a checkpoint.bin
// that loads as an hns checkpoint (a run of an hns from before the marker). Anything else is refused
// (ConfigError), so that no file of the user's is ever removed or overwritten, --overwrite included.
void check_run_folder(const std::string& dir);

// A folder holds a run only once a checkpoint is there (a run stopped before its first checkpoint, by a NaN
// or a crash in its first iterations, cannot be resumed, so the same command starts it over): refused
// unless `overwrite`.
void check_no_run_unless(bool overwrite, const std::string& dir, const std::string& ckpt);

// The run folder `dir`, locked for this process (ppo::FolderLock): a second hns train into a folder that a
// running one uses is refused at start (ConfigError, exit 2), naming the running one's process.
ppo::FolderLock lock_run_folder(const std::string& flag, const std::string& dir);

}  // namespace hns::tools
