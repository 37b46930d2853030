// libFuzzer target: an episode header as a hostile file could hold it. The input is the header's JSON text;
// the target builds a file around it (a valid file header, the header re-summed so that the mutation reaches
// the field checks, a zero payload of the size the header announces) and decodes it. Only TrajectoryError may
// come out, and a header that is accepted names one of hns's scenes and layouts (the pages show them).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "batch/scenes.hpp"
#include "physics/scene.hpp"
#include "replay/trajectory.hpp"

namespace {

using hns::replay::trajectory_checksum;
using nlohmann::json;

// A chunk as docs/trajectory-format.md writes it, with its header checksum.
std::string chunk(json header, const std::string& payload) {
  json rest = header;
  rest.erase("header_fnv1a64");
  header["header_fnv1a64"] = trajectory_checksum(rest.dump());
  std::string text = header.dump();
  while ((4 + text.size()) % 8 != 0) text += ' ';
  const uint32_t n = uint32_t(text.size());
  return std::string(reinterpret_cast<const char*>(&n), 4) + text + payload;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const json header =
      json::parse(std::string_view(reinterpret_cast<const char*>(data), size), nullptr, false);
  if (header.is_discarded() || !header.is_object()) return 0;
  const json file_header = {
      {"kind", "file"},    {"format", "hns-trajectory"}, {"version", hns::replay::kTrajectoryVersion},
      {"episodes", 1},     {"created_by", "fuzz"},       {"policy", "random"},
      {"payload_bytes", 0}};
  uint64_t payload_bytes = 0;
  if (header.contains("payload_bytes") && header["payload_bytes"].is_number_unsigned())
    payload_bytes = std::min<uint64_t>(header["payload_bytes"].get<uint64_t>(), 1 << 20);
  json ep = header;
  const std::string payload(payload_bytes, '\0');
  if (ep.contains("payload_fnv1a64")) ep["payload_fnv1a64"] = trajectory_checksum(payload);
  const std::string bytes =
      std::string(hns::replay::kTrajectoryMagic) + chunk(file_header, "") + chunk(ep, payload);
  try {
    const hns::replay::TrajectoryFile f = hns::replay::decode_trajectory(bytes);
    for (const hns::replay::TrajectoryEpisode& e : f.episodes) {
      if (hns::batch::find_scene(e.scene) == nullptr) __builtin_trap();
      (void)hns::physics::parse_layout(e.layout);  // a ConfigError here escapes: a finding
    }
  } catch (const hns::replay::TrajectoryError&) {
  }
  return 0;
}
