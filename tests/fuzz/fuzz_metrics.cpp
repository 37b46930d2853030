// libFuzzer target: a metrics.jsonl text as `hns report` reads it, then its stages and its detectors per
// window (a window size taken from the input's length). Only MetricsError may come out.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "replay/metrics.hpp"
#include "replay/stages.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const hns::replay::MetricsRows rows =
        hns::replay::read_metrics_jsonl(std::string_view(reinterpret_cast<const char*>(data), size));
    hns::replay::detect_stages(rows, size % 2 == 0 ? "quadrant" : "full");
    hns::replay::detector_windows(rows, 1 + static_cast<int64_t>(size % 100000)).lines();
  } catch (const hns::replay::MetricsError&) {
  }
  return 0;
}
