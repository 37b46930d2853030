// libFuzzer target: a trajectory file as `hns replay` reads it, once with its payload checksums verified and
// once without (so that mutated payloads reach the block and value checks). Only TrajectoryError may come
// out.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "replay/trajectory.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  for (const bool verify : {true, false}) {
    try {
      hns::replay::decode_trajectory(bytes, verify);
    } catch (const hns::replay::TrajectoryError&) {
    }
  }
  return 0;
}
