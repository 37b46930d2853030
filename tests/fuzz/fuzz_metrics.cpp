// libFuzzer target: a metrics.jsonl text as `hns report` reads it. Only MetricsError may come out.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "replay/metrics.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    hns::replay::read_metrics_jsonl(std::string_view(reinterpret_cast<const char*>(data), size));
  } catch (const hns::replay::MetricsError&) {
  }
  return 0;
}
