#include <nlohmann/json.hpp>

#include <charconv>
#include <cstdio>
#include <filesystem>
#include <system_error>

#include "cli.hpp"
#include "physics/scene.hpp"
#include "ppo/atomic_file.hpp"

namespace hns::tools {

namespace fs = std::filesystem;

void check_output_path(const std::string& flag, const std::string& path,
                       const std::vector<std::string>& inputs) {
  auto reject = [&](const std::string& why) { throw physics::ConfigError(flag + " " + path + ": " + why); };
  if (path.empty()) reject("an output file name is required");
  std::error_code ec;
  if (fs::is_directory(path, ec)) reject("is a folder, not a file");
  const fs::path parent = fs::path(path).parent_path().empty() ? fs::path(".") : fs::path(path).parent_path();
  if (!fs::is_directory(parent, ec)) reject("its folder " + parent.string() + " does not exist");
  if (::access(parent.c_str(), W_OK | X_OK) != 0)
    reject("its folder " + parent.string() + " is not writable");
  if (fs::exists(path, ec) && ::access(path.c_str(), W_OK) != 0) reject("exists and is not writable");
  const fs::path out = fs::weakly_canonical(path, ec);
  for (const std::string& in : inputs) {
    std::error_code e2;
    if (!in.empty() && fs::weakly_canonical(in, e2) == out)
      reject("is also an input of this command; choose another file");
  }
}

uint64_t parse_seed(const std::string& flag, const std::string& text) {
  uint64_t value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, err] = std::from_chars(text.data(), end, value);
  if (text.empty() || text[0] == '-' || text[0] == '+' || err != std::errc() || ptr != end) {
    throw physics::ConfigError(flag + " = " + text +
                               " is invalid: must be a whole number in [0, 18446744073709551615]");
  }
  return value;
}

std::string threads_text(int requested) {
  const int used = usable_threads(requested);
  if (requested > used) {
    return std::to_string(requested) + " threads requested, " + std::to_string(used) +
           " available: " + std::to_string(used) + " used";
  }
  return std::to_string(used) + (used == 1 ? " thread" : " threads");
}

void write_atomically(const std::string& path, const std::string& text) {
  ppo::write_file_atomically(path, text);
}

void write_chrome_trace(const std::string& path, const std::vector<batch::TraceEvent>& events) {
  nlohmann::json trace = nlohmann::json::array();
  for (const batch::TraceEvent& ev : events) {
    nlohmann::json e = {{"name", ev.phase},
                        {"cat", ev.thread < 0 ? "trainer" : "batch"},
                        {"ph", "X"},
                        {"ts", ev.begin_ns / 1000.0},
                        {"dur", (ev.end_ns - ev.begin_ns) / 1000.0},
                        {"pid", 1},
                        {"tid", ev.thread < 0 ? 1000 : ev.thread}};
    if (ev.env >= 0) e["args"] = {{"env", ev.env}};
    trace.push_back(std::move(e));
  }
  trace.push_back(
      {{"name", "thread_name"}, {"ph", "M"}, {"pid", 1}, {"tid", 1000}, {"args", {{"name", "trainer"}}}});
  write_atomically(path, nlohmann::json{{"traceEvents", trace}, {"displayTimeUnit", "ms"}}.dump() + "\n");
}

}  // namespace hns::tools
