#include <nlohmann/json.hpp>

#include "cli.hpp"
#include "ppo/atomic_file.hpp"

namespace hns::tools {

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
