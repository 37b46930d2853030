// libFuzzer target: a training config file (TrainConfig::merge_json, then validate). The only error a user
// may see is a ConfigError naming the field; anything else (a crash, a hang, another exception) is a finding.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "physics/scene.hpp"
#include "ppo/train_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  hns::ppo::TrainConfig config;
  try {
    config.merge_json(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz input");
    config.validate();
  } catch (const hns::physics::ConfigError&) {
  }
  return 0;
}
