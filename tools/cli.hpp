// Shared pieces of the hns command line: how a command registers itself, and file helpers.
#pragma once

#include <CLI/CLI.hpp>

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

// Writes `text` to `path` atomically: a temporary file beside it, then rename. Throws on failure.
void write_atomically(const std::string& path, const std::string& text);

}  // namespace hns::tools
