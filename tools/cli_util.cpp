#include <nlohmann/json.hpp>

#include <unistd.h>
#include <climits>

#include <cctype>
#include <charconv>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <system_error>

#include "batch/scenes.hpp"
#include "cli.hpp"
#include "nn/kernels.hpp"
#include "physics/scene.hpp"
#include "ppo/atomic_file.hpp"
#include "ppo/trainer.hpp"

namespace hns::tools {

namespace fs = std::filesystem;

void check_output_path(const std::string& flag, const std::string& path,
                       const std::vector<std::string>& inputs) {
  auto reject = [&](const std::string& why) { throw physics::ConfigError(flag + " " + path + ": " + why); };
  check_output_name(flag, path);
  std::error_code ec;
  if (fs::is_directory(path, ec)) reject("is a folder, not a file");
  const fs::path parent = fs::path(path).parent_path().empty() ? fs::path(".") : fs::path(path).parent_path();
  if (!fs::is_directory(parent, ec)) reject("its folder " + parent.string() + " does not exist");
  try {
    ppo::check_replaceable(path, "");
  } catch (const ppo::FileError& e) {
    throw physics::ConfigError(flag + " " + e.what());
  }
  if (fs::exists(path, ec) && ::access(path.c_str(), W_OK) != 0) reject("exists and is not writable");
  // Whether the file can really be written there (access() says yes for root in /proc, and on a full or
  // read-only mount the answer comes from the write): PATH.tmp, which the atomic write uses, is created and
  // removed.
  check_not_an_input(flag, path, inputs);
  try {
    ::close(ppo::create_temp_file(path + ".tmp"));
    ::unlink((path + ".tmp").c_str());
  } catch (const std::runtime_error& e) {
    reject(std::string("cannot be written: ") + e.what());
  }
}

void check_not_an_input(const std::string& flag, const std::string& path,
                        const std::vector<std::string>& inputs) {
  auto reject = [&](const std::string& why) { throw physics::ConfigError(flag + " " + path + ": " + why); };
  std::error_code ec;
  const fs::path out = fs::weakly_canonical(path, ec);
  const fs::path out_tmp = fs::weakly_canonical(path + ".tmp", ec);
  for (const std::string& in : inputs) {
    std::error_code e2;
    const fs::path p = in.empty() ? fs::path() : fs::weakly_canonical(in, e2);
    if (!in.empty() && p == out) reject("is also an input of this command; choose another file");
    if (!in.empty() && p == out_tmp)
      reject("is written through " + path + ".tmp, which is an input of this command; choose another file");
  }
}

void check_output_name(const std::string& flag, const std::string& path) {
  if (path.empty()) throw physics::ConfigError(flag + ": an output file name is required");
  check_path_length(flag, path);
  const size_t name_bytes = fs::path(path).filename().native().size();
  if (name_bytes + 4 > NAME_MAX) {
    throw physics::ConfigError(
        flag + " " + path + ": its name is too long to write PATH.tmp beside it first (" +
        std::to_string(name_bytes) + " bytes; at most " + std::to_string(NAME_MAX - 4) + ")");
  }
}

void check_path_length(const std::string& flag, const std::string& path) {
  if (path.size() >= PATH_MAX) {
    throw physics::ConfigError(flag + ": the path is too long (" + std::to_string(path.size()) +
                               " bytes; at most " + std::to_string(PATH_MAX - 1) + ")");
  }
  for (const fs::path& part : fs::path(path)) {
    if (part.native().size() > NAME_MAX) {
      throw physics::ConfigError(flag + " " + path.substr(0, 60) + "...: a name in the path is too long (" +
                                 std::to_string(part.native().size()) + " bytes; at most " +
                                 std::to_string(NAME_MAX) + ")");
    }
  }
}

namespace {
// FNV-1a 64 of a file's bytes as 16 hex digits.
std::string file_fingerprint(const std::string& path) {
  const std::string bytes = ppo::read_regular_file(path, ppo::kMaxCheckpointBytes, "checkpoint");
  const uint64_t h = ppo::fnv1a64(bytes.data(), bytes.size());
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}
}  // namespace

std::vector<Condition> parse_conditions(const std::string& seed_label,
                                        const std::vector<std::string>& pretrained,
                                        const std::string& model) {
  namespace fs = std::filesystem;
  std::vector<Condition> conditions = {{seed_label, "", ""}};
  for (const std::string& p : pretrained) {
    const std::string flag = "--pretrained " + p;
    const auto eq = p.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == p.size())
      throw physics::ConfigError(flag + ": expected LABEL=CHECKPOINT");
    const std::string label = p.substr(0, eq);
    for (char ch : label) {
      if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '-' || ch == '_'))
        throw physics::ConfigError(flag + ": the label may hold letters, digits, - and _ only");
    }
    for (const Condition& other : conditions) {
      if (other.label == label)
        throw physics::ConfigError("--pretrained: label '" + label + "' is used twice");
    }
    Condition c{label, p.substr(eq + 1), ""};
    std::error_code ec;
    if (!fs::is_regular_file(c.checkpoint, ec))
      throw physics::ConfigError(flag + ": no such checkpoint file");
    c.checkpoint = fs::absolute(c.checkpoint).lexically_normal().string();
    ppo::TrainConfig theirs;
    try {
      theirs = ppo::Trainer::checkpoint_config(c.checkpoint);
    } catch (const std::runtime_error& e) {
      throw physics::ConfigError(flag + ": " + e.what());
    }
    if (theirs.model != model) {
      throw physics::ConfigError(flag + ": the checkpoint's model is " + theirs.model +
                                 ", this command's is " + model + " (--model)");
    }
    try {
      c.fingerprint = file_fingerprint(c.checkpoint);
    } catch (const std::exception& e) {
      throw physics::ConfigError(flag + ": " + e.what());
    }
    conditions.push_back(c);
  }
  return conditions;
}

uint64_t parse_seed(const std::string& flag, const std::string& text) {
  uint64_t value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, err] = std::from_chars(text.data(), end, value);
  const bool leading_zero = text.size() > 1 && text[0] == '0';
  if (text.empty() || text[0] == '-' || text[0] == '+' || leading_zero || err != std::errc() || ptr != end) {
    throw physics::ConfigError(flag + " = " + text +
                               " is invalid: must be a whole number in [0, 18446744073709551615]");
  }
  return value;
}

std::string count_text(long long n, const std::string& noun, const std::string& plural_noun) {
  return std::to_string(n) + " " + (n == 1 ? noun : plural_noun.empty() ? noun + "s" : plural_noun);
}

std::string scene_help() {
  auto pad = [](std::string s, size_t width) {
    s.resize(std::max(s.size() + 1, width), ' ');
    return s;
  };
  std::string text = "Scenes:\n";
  for (const batch::SceneInfo& s : batch::kScenes)
    text += "  " + pad(s.name, 18) + pad(batch::family_name(s.family), 15) + s.summary + "\n";
  return text;
}

std::string threads_text(int requested) {
  const int used = usable_threads(requested);
  if (requested > used) {
    return std::to_string(requested) + " threads requested, " + std::to_string(used) +
           " available: " + std::to_string(used) + " used";
  }
  return std::to_string(used) + (used == 1 ? " thread" : " threads");
}

nlohmann::json build_and_machine() {
  std::string cpu = "unknown";
  std::ifstream info("/proc/cpuinfo");
  for (std::string line; std::getline(info, line);) {
    if (line.rfind("model name", 0) == 0 && line.find(':') != std::string::npos) {
      cpu = line.substr(line.find(':') + 1);
      cpu.erase(0, cpu.find_first_not_of(' '));
      break;
    }
  }
  return {{"hns_version", kHnsVersion},
          {"commit", kHnsCommit},
          {"cpu_model", cpu},
          {"isa", nn::kernels::isa_description()}};
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
