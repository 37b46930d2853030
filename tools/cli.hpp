// Shared pieces of the hns command line: how a command registers itself, and file helpers.
#pragma once

#include <CLI/CLI.hpp>

#include "batch/batch_sim.hpp"

#include <functional>
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

// Writes trace events as a Chrome trace (chrome://tracing, ui.perfetto.dev), atomically: one row per
// thread (TBB worker index; thread -1 is the trainer's own thread, shown as "trainer"), one box per phase
// (and env, where the event has one).
void write_chrome_trace(const std::string& path, const std::vector<batch::TraceEvent>& events);

// Writes `text` to `path` atomically: a temporary file beside it, then rename. Throws on failure.
void write_atomically(const std::string& path, const std::string& text);

}  // namespace hns::tools
