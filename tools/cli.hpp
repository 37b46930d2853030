// Shared pieces of the hns command line: how a command registers itself, and file helpers.
#pragma once

#include <CLI/CLI.hpp>

#include "batch/batch_sim.hpp"
#include "batch/host.hpp"

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace hns::tools {

// A subcommand and what runs it once parsed. run() returns the exit status; it may throw
// physics::ConfigError (bad input, exit 2) or std::exception (runtime failure, exit 1).
struct Command {
  CLI::App* app;
  std::function<int()> run;
};

// Each command file adds its subcommand and options.
void add_bench_command(CLI::App& app, std::vector<Command>& commands);
void add_play_command(CLI::App& app, std::vector<Command>& commands);
void add_replay_command(CLI::App& app, std::vector<Command>& commands);
void add_train_command(CLI::App& app, std::vector<Command>& commands);
void add_report_command(CLI::App& app, std::vector<Command>& commands);
void add_eval_command(CLI::App& app, std::vector<Command>& commands);
void add_counting_command(CLI::App& app, std::vector<Command>& commands);
void add_export_command(CLI::App& app, std::vector<Command>& commands);

// Writes trace events as a Chrome trace (chrome://tracing, ui.perfetto.dev), atomically: one row per
// thread (TBB worker index; thread -1 is the trainer's own thread, shown as "trainer"), one box per phase
// (and env, where the event has one).
void write_chrome_trace(const std::string& path, const std::vector<batch::TraceEvent>& events);

// Writes `text` to `path` atomically: a temporary file beside it, then rename. Throws on failure.
void write_atomically(const std::string& path, const std::string& text);

// Checks, before any work starts, that the file `path` given to `flag` can be written: its name is not too
// long, it is not a folder nor another special file (a device or FIFO would be replaced by the atomic write),
// its folder exists and takes a new file (tried: PATH.tmp is created and removed), and it is none of `inputs`
// (files the command reads). Throws physics::ConfigError naming the flag and the reason.
void check_output_path(const std::string& flag, const std::string& path,
                       const std::vector<std::string>& inputs = {});

// The part of check_output_path that needs no file system: `path` (and PATH.tmp, which the atomic write uses)
// is none of `inputs`, compared as absolute paths with `..` and links resolved where they exist.
void check_not_an_input(const std::string& flag, const std::string& path,
                        const std::vector<std::string>& inputs);

// The project version and the git commit of the source it was built from ("unknown" outside a checkout;
// "-dirty" when the tree had changes), written at build time by cmake/HnsVersion.cmake.
extern const char* const kHnsVersion;
extern const char* const kHnsCommit;

// What a benchmark figure needs to be traced to its machine and build: hns's version and commit, the CPU's
// model name (/proc/cpuinfo) and the instruction set the binary runs. Added to every `bench --json`.
nlohmann::json build_and_machine();

// The checks of check_output_path that need no file system (so they can refuse before a folder the file goes
// into exists): a name is given, check_path_length, and the name leaves room for PATH.tmp's.
void check_output_name(const std::string& flag, const std::string& path);

// Refuses (physics::ConfigError naming `flag`) a path longer than PATH_MAX or with a name longer than
// NAME_MAX, which the file system would refuse only once the work is done.
void check_path_length(const std::string& flag, const std::string& path);

// A seed given to `flag`: a decimal integer in [0, 2^64 - 1], nothing else (no sign, exponent or fraction).
// Throws physics::ConfigError.
uint64_t parse_seed(const std::string& flag, const std::string& text);

// A condition of `hns eval` or `hns counting`: the networks from the seed (`label` the command's own name
// for it, checkpoint "") or from a --pretrained LABEL=CHECKPOINT.
struct Condition {
  std::string label;
  std::string checkpoint;   // absolute path, "" for the seed's networks
  std::string fingerprint;  // FNV-1a 64 of the checkpoint file, 16 hex digits
};
// The seed's condition `seed_label`, then one per --pretrained value: LABEL (letters, digits, - and _,
// unique) = a readable checkpoint of `model`, identified by its bytes. Throws physics::ConfigError naming
// the bad value.
std::vector<Condition> parse_conditions(const std::string& seed_label,
                                        const std::vector<std::string>& pretrained, const std::string& model);

// Worker threads and memory: the batch library's (shared with the Python module).
using batch::check_memory;
using batch::usable_threads;
// "T threads" or, when the machine has fewer, "T threads requested, U available: U used".
std::string threads_text(int requested);
// The --help footer of the commands that take --scene: every scene of batch::kScenes with its family and
// one-line summary.
std::string scene_help();
// "1 env", "2 envs": n and the noun, plural unless n is 1 (plural_noun: noun + "s" when not given).
std::string count_text(long long n, const std::string& noun, const std::string& plural_noun = "");

}  // namespace hns::tools
