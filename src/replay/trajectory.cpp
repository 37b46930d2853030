// Trajectory files: encoding, streaming writes and a checking decoder (format: docs/trajectory-format.md).
#include "replay/trajectory.hpp"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "batch/scenes.hpp"
#include "physics/scene.hpp"
#include "ppo/atomic_file.hpp"
#include "replay/metrics.hpp"

namespace hns::replay {
namespace {

using nlohmann::json;

static_assert(std::endian::native == std::endian::little, "trajectory blocks are written in host order");

template <class T>
struct DType;
template <>
struct DType<float> {
  static constexpr const char* kName = "f32";
};
template <>
struct DType<uint8_t> {
  static constexpr const char* kName = "u8";
};
template <>
struct DType<int8_t> {
  static constexpr const char* kName = "i8";
};
template <>
struct DType<uint16_t> {
  static constexpr const char* kName = "u16";
};

using Shape = std::vector<int64_t>;

// Calls f(name, block vector, shape, what the axes are) for every block, in file order.
template <class Episode, class F>
void for_each_block(Episode& ep, F&& f) {
  const int64_t n = ep.frames, a = ep.num_agents(), b = ep.num_boxes, r = ep.num_ramps;
  const int64_t o = b + r;
  f("agent_pose", ep.agent_pose, Shape{n, a, 4}, "frames x agents x 4");
  f("box_pose", ep.box_pose, Shape{n, b, 4}, "frames x boxes x 4");
  f("ramp_pose", ep.ramp_pose, Shape{n, r, 4}, "frames x ramps x 4");
  f("object_lock", ep.object_lock, Shape{n, o}, "frames x objects");
  f("object_locker", ep.object_locker, Shape{n, o}, "frames x objects");
  f("agent_holding", ep.agent_holding, Shape{n, a}, "frames x agents");
  f("vis_agents", ep.vis_agents, Shape{n, a, a}, "frames x agents x agents");
  f("vis_boxes", ep.vis_boxes, Shape{n, a, b}, "frames x agents x boxes");
  f("vis_ramps", ep.vis_ramps, Shape{n, a, r}, "frames x agents x ramps");
  f("lidar", ep.lidar, Shape{n, a, kTrajectoryLidarRays}, "frames x agents x 30");
  f("reward", ep.reward, Shape{n, a}, "frames x agents");
  f("prep", ep.prep, Shape{n}, "frames");
  f("action", ep.action, Shape{n, a, kActionFields}, "frames x agents x 5");
  f("food", ep.food, Shape{n, ep.num_food, 4}, "frames x food x 4");  // absent before the food variants
}

int64_t elements(const Shape& shape) {
  int64_t count = 1;
  for (int64_t d : shape) count *= d;
  return count;
}

std::string shape_text(const Shape& shape) {
  std::string s = "[";
  for (size_t i = 0; i < shape.size(); ++i) {
    if (i > 0) s += ',';
    s += std::to_string(shape[i]);
  }
  return s + "]";
}

uint64_t align8(uint64_t x) {
  return (x + 7) & ~uint64_t(7);
}

// The checksum of a chunk's header (version 3): FNV-1a 64 of the header's compact JSON (keys sorted, as
// nlohmann::json writes them) without the "header_fnv1a64" key itself.
std::string header_checksum(json header) {
  header.erase("header_fnv1a64");
  return trajectory_checksum(header.dump());
}

// A chunk: u32 length, JSON padded with spaces so the payload starts 8-byte aligned, payload.
std::string make_chunk(json header, const std::string& payload) {
  header["payload_bytes"] = payload.size();
  header["header_fnv1a64"] = header_checksum(header);
  std::string text = header.dump();
  text.append(align8(4 + text.size()) - 4 - text.size(), ' ');
  std::string out(4, '\0');
  const uint32_t length = uint32_t(text.size());
  std::memcpy(out.data(), &length, 4);
  out += text;
  out += payload;
  return out;
}

std::string file_chunk(const TrajectoryFile& meta, int episodes) {
  json h;
  h["kind"] = "file";
  h["format"] = "hns-trajectory";
  h["version"] = kTrajectoryVersion;
  h["episodes"] = episodes;
  h["created_by"] = meta.created_by;
  h["policy"] = meta.policy;
  return make_chunk(std::move(h), "");
}

}  // namespace

std::string trajectory_checksum(std::string_view payload) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (const char c : payload) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ULL;
  }
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

namespace {

std::string episode_chunk(const TrajectoryEpisode& ep) {
  json h;
  h["kind"] = "episode";
  h["version"] = kTrajectoryVersion;
  h["scene"] = ep.scene;
  h["layout"] = ep.layout;
  h["seed"] = ep.seed;
  h["env"] = ep.env;
  h["episode"] = ep.episode;
  h["horizon"] = ep.horizon;
  h["prep_steps"] = ep.prep_steps;
  h["step_time"] = ep.step_time;
  h["frames"] = ep.frames;
  h["num_hiders"] = ep.num_hiders;
  h["num_seekers"] = ep.num_seekers;
  h["num_boxes"] = ep.num_boxes;
  h["num_elongated"] = ep.num_elongated;
  h["num_ramps"] = ep.num_ramps;
  h["num_food"] = ep.num_food;
  h["outer_walls"] = ep.outer_walls;
  h["walls"] = ep.walls;
  h["cylinders"] = ep.cylinders;
  h["sites"] = ep.sites;
  h["box_sizes"] = ep.box_sizes;
  h["restrict_rect"] = ep.restrict_rect;
  h["hider_return"] = ep.hider_return;
  h["seeker_return"] = ep.seeker_return;
  h["lidar_rays"] = kTrajectoryLidarRays;
  h["lidar_unit"] = kLidarUnit;
  // Informative constants for readers that draw the scene (docs/game.md §1.2).
  h["agent_radius"] = 0.15;
  h["ramp_size"] = 0.5;

  std::string payload;
  json blocks = json::array();
  for_each_block(ep, [&](const char* name, const auto& data, const Shape& shape, const char*) {
    using T = typename std::decay_t<decltype(data)>::value_type;
    if (int64_t(data.size()) != elements(shape)) {
      throw std::logic_error(std::string("trajectory block ") + name + " holds " +
                             std::to_string(data.size()) + " values, its shape " + shape_text(shape) +
                             " needs " + std::to_string(elements(shape)));
    }
    payload.resize(align8(payload.size()), '\0');
    blocks.push_back(
        {{"name", name}, {"dtype", DType<T>::kName}, {"shape", shape}, {"offset", payload.size()}});
    payload.append(reinterpret_cast<const char*>(data.data()), data.size() * sizeof(T));
  });
  payload.resize(align8(payload.size()), '\0');
  h["blocks"] = std::move(blocks);
  h["payload_fnv1a64"] = trajectory_checksum(payload);
  return make_chunk(std::move(h), payload);
}

// Reads the fields of one header and says which one is wrong.
class Fields {
 public:
  Fields(const json& j, std::string where) : j_(j), where_(std::move(where)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw TrajectoryError(where_ + ": field \"" + key + "\": " + what);
  }
  bool has(const std::string& key) const { return j_.contains(key); }
  const json& at(const std::string& key) const {
    auto it = j_.find(key);
    if (it == j_.end()) fail(key, "missing");
    return *it;
  }
  std::string got(const json& v) const {
    std::string s = v.dump();
    if (s.size() > 40) s = s.substr(0, 37) + "...";
    return ", got " + s;
  }
  int64_t integer(const std::string& key, int64_t lo, int64_t hi) const {
    const json& v = at(key);
    const std::string range =
        "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    if (!v.is_number_integer()) fail(key, range + got(v));
    if (v.is_number_unsigned() ? v.get<uint64_t>() > uint64_t(hi)
                               : (v.get<int64_t>() < lo || v.get<int64_t>() > hi))
      fail(key, range + got(v));
    return v.get<int64_t>();
  }
  uint64_t unsigned_integer(const std::string& key) const {
    const json& v = at(key);
    if (!v.is_number_unsigned()) fail(key, "expected a non-negative integer" + got(v));
    return v.get<uint64_t>();
  }
  double number(const std::string& key, double lo, double hi) const {
    const json& v = at(key);
    if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < lo || v.get<double>() > hi) {
      std::ostringstream range;
      range << "expected a number in [" << lo << ", " << hi << "]";
      fail(key, range.str() + got(v));
    }
    return v.get<double>();
  }
  std::string string(const std::string& key) const {
    const json& v = at(key);
    if (!v.is_string() || v.get<std::string>().empty() || v.get<std::string>().size() > 256)
      fail(key, "expected a non-empty string" + got(v));
    return v.get<std::string>();
  }
  bool boolean(const std::string& key) const {
    const json& v = at(key);
    if (!v.is_boolean()) fail(key, "expected true or false" + got(v));
    return v.get<bool>();
  }
  // An array of `count` rows (count < 0: any) of `width` finite numbers each.
  template <size_t W>
  std::vector<std::array<double, W>> rows(const std::string& key, int64_t count) const {
    const json& v = at(key);
    if (!v.is_array()) fail(key, "expected an array" + got(v));
    if (count >= 0 && int64_t(v.size()) != count)
      fail(key, "expected " + std::to_string(count) + " entries, got " + std::to_string(v.size()));
    std::vector<std::array<double, W>> out(v.size());
    for (size_t i = 0; i < v.size(); ++i) {
      const json& row = v[i];
      if (!row.is_array() || row.size() != W) {
        fail(key, "entry " + std::to_string(i) + ": expected " + std::to_string(W) + " numbers" + got(row));
      }
      for (size_t k = 0; k < W; ++k) {
        if (!row[k].is_number() || !std::isfinite(row[k].get<double>()))
          fail(key, "entry " + std::to_string(i) + ": expected finite numbers" + got(row));
        out[i][k] = row[k].get<double>();
      }
    }
    return out;
  }
  // A flat array of W finite numbers.
  template <size_t W>
  std::array<double, W> numbers(const std::string& key) const {
    const json& v = at(key);
    std::array<double, W> out{};
    if (!v.is_array() || v.size() != W) fail(key, "expected " + std::to_string(W) + " numbers" + got(v));
    for (size_t k = 0; k < W; ++k) {
      if (!v[k].is_number() || !std::isfinite(v[k].get<double>()))
        fail(key, "expected finite numbers" + got(v));
      out[k] = v[k].get<double>();
    }
    return out;
  }

 private:
  const json& j_;
  std::string where_;
};

struct Chunk {
  json header;
  uint64_t payload_pos = 0;
  uint64_t payload_bytes = 0;
};

// Reads the chunk at `pos`; `what` names it in errors ("file header", "episode 3").
Chunk read_chunk(std::string_view bytes, uint64_t& pos, const std::string& what, bool verify_checksums) {
  const std::string where = "byte " + std::to_string(pos) + " (" + what + ")";
  if (bytes.size() - pos < 4) {
    throw TrajectoryError(where + ": the file ends before the header length (truncated file?)");
  }
  uint32_t length = 0;
  std::memcpy(&length, bytes.data() + pos, 4);
  if (length > bytes.size() - pos - 4) {
    throw TrajectoryError(where + ": header length " + std::to_string(length) +
                          " runs past the end of the file (" + std::to_string(bytes.size()) +
                          " bytes; truncated file?)");
  }
  Chunk c;
  if (!json_nesting_within(std::string_view(bytes).substr(pos + 4, length))) {
    throw TrajectoryError(where + ": header nests arrays or objects more than " +
                          std::to_string(kMaxJsonDepth) + " levels deep");
  }
  try {
    c.header = json::parse(bytes.substr(pos + 4, length));
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number beyond a double's range
    throw TrajectoryError(where + ": header is not valid JSON: " + e.what());
  }
  if (!c.header.is_object()) throw TrajectoryError(where + ": header is not a JSON object");
  // Version 3 headers carry their own checksum (required there, checked in decode_trajectory's version
  // logic); one that is present is always checked, whatever version the (maybe damaged) file claims.
  if (verify_checksums && c.header.contains("header_fnv1a64")) {
    const json& stored = c.header["header_fnv1a64"];
    const std::string actual = header_checksum(c.header);
    if (!stored.is_string() || stored.get<std::string>() != actual) {
      throw TrajectoryError(
          where + ": \"header_fnv1a64\": the header's checksum is " + actual + ", the header says " +
          (stored.is_string() ? stored.get<std::string>() : stored.dump()) + " (a corrupt file)");
    }
  }
  c.payload_pos = pos + 4 + length;
  if (c.payload_pos % 8 != 0) {
    throw TrajectoryError(where + ": header length " + std::to_string(length) +
                          " leaves the payload unaligned (headers are space-padded to 8 bytes)");
  }
  const Fields f(c.header, where);
  c.payload_bytes = f.unsigned_integer("payload_bytes");
  if (c.payload_bytes % 8 != 0)
    f.fail("payload_bytes", "not a multiple of 8 (payloads are zero-padded to 8 bytes)");
  if (c.payload_bytes > bytes.size() - c.payload_pos) {
    throw TrajectoryError(where + ": payload of " + std::to_string(c.payload_bytes) +
                          " bytes runs past the end of the file (" + std::to_string(bytes.size()) +
                          " bytes; truncated file?)");
  }
  pos = c.payload_pos + c.payload_bytes;
  return c;
}

// Checks every value of a block; bad(value) returns what was expected, or nullptr if the value is fine.
template <class T, class Bad>
void check_values(const std::vector<T>& data, int64_t per_frame, const std::string& where, const char* name,
                  Bad bad) {
  for (size_t i = 0; i < data.size(); ++i) {
    if (const char* expected = bad(data[i])) {
      std::ostringstream msg;
      msg << where << ": block \"" << name << "\": frame " << i / per_frame << ", element " << i % per_frame
          << ": value " << +data[i] << ", expected " << expected;
      throw TrajectoryError(msg.str());
    }
  }
}

// The chunk is an episode of the file's version, and (where asked) its payload matches its checksum.
void check_episode_chunk(std::string_view bytes, const Chunk& c, const Fields& f, int version,
                         bool verify_checksum) {
  if (!c.header.contains("kind") || c.header["kind"] != "episode") {
    f.fail("kind", "expected \"episode\"" + (c.header.contains("kind") ? f.got(c.header["kind"]) : ""));
  }
  if (f.integer("version", 0, 1 << 30) != version) {
    f.fail("version", "the file header says version " + std::to_string(version) + f.got(c.header["version"]));
  }
  if (version >= 2) {
    const std::string stored = f.string("payload_fnv1a64");
    const std::string actual = trajectory_checksum(bytes.substr(c.payload_pos, c.payload_bytes));
    if (verify_checksum && stored != actual) {
      f.fail("payload_fnv1a64",
             "the payload's checksum is " + actual + ", the header says " + stored + " (a corrupt file)");
    }
  }
}

// The header's scalars and geometry, each within what hns can have written.
void read_episode_header(const Fields& f, const Chunk& c, TrajectoryEpisode& ep) {
  // Names the pages show: only hns's own (a page built from a file someone sent must not take markup from
  // it).
  ep.scene = f.string("scene");
  if (batch::find_scene(ep.scene) == nullptr)
    f.fail("scene", "is not a scene of hns" + f.got(c.header["scene"]));
  ep.layout = f.string("layout");
  try {
    (void)physics::parse_layout(ep.layout);
  } catch (const physics::ConfigError&) {
    f.fail("layout", "is not a layout of hns" + f.got(c.header["layout"]));
  }
  ep.seed = f.unsigned_integer("seed");
  ep.env = int(f.integer("env", 0, 1 << 30));
  ep.episode = int(f.integer("episode", 0, std::numeric_limits<int>::max()));
  ep.horizon = int(f.integer("horizon", 1, kTrajectoryMaxFrames - 1));
  ep.prep_steps = int(f.integer("prep_steps", 0, ep.horizon));
  ep.step_time = f.number("step_time", 1e-6, 10.0);
  ep.frames = int(f.integer("frames", 1, ep.horizon + 1));
  ep.num_hiders = int(f.integer("num_hiders", 0, kTrajectoryMaxAgents));
  ep.num_seekers = int(f.integer("num_seekers", 0, kTrajectoryMaxAgents - ep.num_hiders));
  if (ep.num_agents() == 0)
    f.fail("num_seekers", "an episode needs at least one agent (num_hiders is 0 too)");
  ep.num_boxes = int(f.integer("num_boxes", 0, kTrajectoryMaxObjects));
  ep.num_elongated = int(f.integer("num_elongated", 0, ep.num_boxes));
  ep.num_ramps = int(f.integer("num_ramps", 0, kTrajectoryMaxObjects - ep.num_boxes));
  if (f.has("num_food")) ep.num_food = int(f.integer("num_food", 0, kTrajectoryMaxObjects));  // 0 before food
  ep.outer_walls = f.boolean("outer_walls");
  ep.walls = f.rows<6>("walls", -1);
  if (f.has("cylinders")) ep.cylinders = f.rows<4>("cylinders", -1);  // absent before the shelter task
  for (size_t i = 0; i < ep.cylinders.size(); ++i) {
    if (ep.cylinders[i][2] <= 0 || ep.cylinders[i][3] <= 0)
      f.fail("cylinders", "entry " + std::to_string(i) + ": radius or height <= 0");
  }
  if (f.has("sites")) ep.sites = f.rows<3>("sites", -1);  // absent before the blueprint task
  for (size_t i = 0; i < ep.sites.size(); ++i) {
    if (ep.sites[i][2] <= 0) f.fail("sites", "entry " + std::to_string(i) + ": edge <= 0");
  }
  ep.box_sizes = f.rows<3>("box_sizes", ep.num_boxes);
  ep.restrict_rect = f.numbers<4>("restrict_rect");
  ep.hider_return = f.number("hider_return", -1e12, 1e12);
  ep.seeker_return = f.number("seeker_return", -1e12, 1e12);
  for (size_t i = 0; i < ep.walls.size(); ++i) {
    const auto& w = ep.walls[i];
    if (w[3] < 0 || w[4] < 0 || w[5] < 0)
      f.fail("walls", "entry " + std::to_string(i) + ": negative half extent");
  }
  // Geometry where a body can be: centres and extents within the bounds every recorded pose keeps.
  const auto bounded = [&](const char* key, const auto& rows, std::initializer_list<int> z_columns) {
    for (size_t i = 0; i < rows.size(); ++i) {
      for (size_t k = 0; k < rows[i].size(); ++k) {
        const bool z = std::find(z_columns.begin(), z_columns.end(), int(k)) != z_columns.end();
        if (std::abs(rows[i][k]) > (z ? kTrajectoryMaxZ : kTrajectoryMaxXY)) {
          f.fail(key, "entry " + std::to_string(i) + ": value " + std::to_string(rows[i][k]) + " is beyond " +
                          std::to_string(z ? kTrajectoryMaxZ : kTrajectoryMaxXY) + " m");
        }
      }
    }
  };
  bounded("walls", ep.walls, {2, 5});
  bounded("cylinders", ep.cylinders, {3});
  bounded("sites", ep.sites, {});
  bounded("box_sizes", ep.box_sizes, {2});
  bounded("restrict_rect", std::vector<std::array<double, 4>>{ep.restrict_rect}, {});
  for (size_t i = 0; i < ep.box_sizes.size(); ++i) {
    const auto& s = ep.box_sizes[i];
    if (s[0] <= 0 || s[1] <= 0 || s[2] <= 0)
      f.fail("box_sizes", "entry " + std::to_string(i) + ": size <= 0");
  }
}

// The blocks: name -> descriptor; every known block must be present with its exact dtype and shape.
void read_episode_blocks(std::string_view bytes, const Chunk& c, const Fields& f, const std::string& where,
                         TrajectoryEpisode& ep) {
  const json& blocks = f.at("blocks");
  if (!blocks.is_array()) f.fail("blocks", "expected an array" + f.got(blocks));
  std::map<std::string, const json*> by_name;
  for (const json& b : blocks) {
    if (!b.is_object() || !b.contains("name") || !b["name"].is_string()) {
      f.fail("blocks", "expected objects with a \"name\"" + f.got(b));
    }
    if (!by_name.emplace(b["name"].get<std::string>(), &b).second) {
      f.fail("blocks", "block \"" + b["name"].get<std::string>() + "\" appears twice");
    }
  }
  const std::string_view payload = bytes.substr(c.payload_pos, c.payload_bytes);
  for_each_block(ep, [&](const char* name, auto& data, const Shape& shape, const char* axes) {
    using T = typename std::decay_t<decltype(data)>::value_type;
    const std::string bwhere = where + ": block \"" + name + "\"";
    auto it = by_name.find(name);
    if (it == by_name.end() && elements(shape) == 0 && std::string_view(name) == "food") {
      data.clear();  // files written before the food variants have no food block
      return;
    }
    if (it == by_name.end()) throw TrajectoryError(bwhere + ": missing");
    const Fields bf(*it->second, bwhere);
    if (bf.string("dtype") != DType<T>::kName) {
      bf.fail("dtype", std::string("expected \"") + DType<T>::kName + "\"" + bf.got(bf.at("dtype")));
    }
    const json& js = bf.at("shape");
    Shape got;
    if (js.is_array()) {
      for (const json& d : js) got.push_back(d.is_number_integer() ? d.get<int64_t>() : -1);
    }
    if (got != shape) {
      bf.fail("shape", "expected " + shape_text(shape) + " (" + axes + ")" + bf.got(js));
    }
    const uint64_t offset = bf.unsigned_integer("offset");
    const uint64_t size = uint64_t(elements(shape)) * sizeof(T);
    if (offset % 8 != 0)
      bf.fail("offset", "not a multiple of 8 (blocks start 8-byte aligned)" + bf.got(bf.at("offset")));
    if (offset > payload.size() || size > payload.size() - offset) {
      throw TrajectoryError(bwhere + ": bytes [" + std::to_string(offset) + ", " +
                            std::to_string(offset + size) + ") run past the payload (" +
                            std::to_string(payload.size()) + " bytes)");
    }
    data.resize(size / sizeof(T));
    if (size > 0) std::memcpy(data.data(), payload.data() + offset, size);
  });
}

// The values: poses and rewards finite and within physical bounds, flags 0/1, indices in range.
void check_episode_values(const TrajectoryEpisode& ep, const std::string& where) {
  const int64_t a = ep.num_agents(), o = ep.num_objects();
  auto flag = [](uint8_t v) -> const char* { return v <= 1 ? nullptr : "0 or 1"; };
  // Each pose is (x, y, z, yaw): the element index within a frame says which.
  auto check_poses = [&](const std::vector<float>& poses, int64_t bodies, const char* name) {
    static const char* const kExpected[4] = {"a finite x within ±200 m", "a finite y within ±200 m",
                                             "a finite z within ±100 m", "a finite yaw within ±4 rad"};
    const double bounds[4] = {kTrajectoryMaxXY, kTrajectoryMaxXY, kTrajectoryMaxZ, kTrajectoryMaxYaw};
    for (size_t i = 0; i < poses.size(); ++i) {
      if (std::abs(poses[i]) <= bounds[i % 4]) continue;
      std::ostringstream msg;
      msg << where << ": block \"" << name << "\": frame " << i / (bodies * 4) << ", element "
          << i % (bodies * 4) << ": value " << poses[i] << ", expected " << kExpected[i % 4];
      throw TrajectoryError(msg.str());
    }
  };
  check_poses(ep.agent_pose, a, "agent_pose");
  check_poses(ep.box_pose, ep.num_boxes, "box_pose");
  check_poses(ep.ramp_pose, ep.num_ramps, "ramp_pose");
  check_values(ep.object_lock, o, where, "object_lock", [](uint8_t v) -> const char* {
    return v <= 2 ? nullptr : "0 (free), 1 (hiders) or 2 (seekers)";
  });
  check_values(ep.object_locker, o, where, "object_locker",
               [a](int8_t v) -> const char* { return v >= -1 && v < a ? nullptr : "-1 or an agent index"; });
  check_values(ep.agent_holding, a, where, "agent_holding",
               [o](int8_t v) -> const char* { return v >= -1 && v < o ? nullptr : "-1 or an object index"; });
  check_values(ep.vis_agents, a * a, where, "vis_agents", flag);
  check_values(ep.vis_boxes, a * ep.num_boxes, where, "vis_boxes", flag);
  check_values(ep.vis_ramps, a * ep.num_ramps, where, "vis_ramps", flag);
  check_values(ep.reward, a, where, "reward", [](float v) -> const char* {
    return std::abs(v) <= kTrajectoryMaxReward ? nullptr : "a finite number within ±10000";
  });
  check_values(ep.prep, 1, where, "prep", flag);
  for (size_t i = 0; i < ep.food.size(); ++i) {
    const float v = ep.food[i];
    const bool ok =
        i % 4 == 3 ? v >= 0 && v <= 1e6f : std::abs(v) <= (i % 4 == 2 ? kTrajectoryMaxZ : kTrajectoryMaxXY);
    if (!ok) {
      std::ostringstream msg;
      msg << where << ": block \"food\": frame " << i / (size_t(ep.num_food) * 4) << ", element "
          << i % (size_t(ep.num_food) * 4) << ": value " << v << ", expected "
          << (i % 4 == 3 ? "units left in [0, 1000000]" : "a finite position within the bounds");
      throw TrajectoryError(msg.str());
    }
  }
  for (size_t i = 0; i < ep.action.size(); ++i) {
    const int field = int(i % kActionFields);
    const int limit = field < 3 ? 10 : 1;
    if (ep.action[i] > limit) {
      throw TrajectoryError(where + ": block \"action\": frame " + std::to_string(i / (a * kActionFields)) +
                            ", agent " + std::to_string(i / kActionFields % a) + ", field " +
                            std::to_string(field) + ": value " + std::to_string(ep.action[i]) +
                            ", expected 0.." + std::to_string(limit));
    }
  }
}

TrajectoryEpisode read_episode(std::string_view bytes, const Chunk& c, const std::string& where, int version,
                               bool verify_checksum) {
  const Fields f(c.header, where);
  check_episode_chunk(bytes, c, f, version, verify_checksum);
  TrajectoryEpisode ep;
  read_episode_header(f, c, ep);
  read_episode_blocks(bytes, c, f, where, ep);
  check_episode_values(ep, where);
  return ep;
}

}  // namespace

void TrajectoryEpisode::resize(int n) {
  frames = n;
  const size_t a = size_t(num_agents()), b = size_t(num_boxes), r = size_t(num_ramps), o = b + r,
               f = size_t(n);
  agent_pose.assign(f * a * 4, 0.0f);
  box_pose.assign(f * b * 4, 0.0f);
  ramp_pose.assign(f * r * 4, 0.0f);
  object_lock.assign(f * o, 0);
  object_locker.assign(f * o, -1);
  agent_holding.assign(f * a, -1);
  vis_agents.assign(f * a * a, 0);
  vis_boxes.assign(f * a * b, 0);
  vis_ramps.assign(f * a * r, 0);
  lidar.assign(f * a * kTrajectoryLidarRays, 0);
  reward.assign(f * a, 0.0f);
  prep.assign(f, 0);
  action.assign(f * a * kActionFields, 0);
  food.assign(f * size_t(num_food) * 4, 0.0f);
}

std::string encode_trajectory(const TrajectoryFile& file) {
  std::string out(kTrajectoryMagic);
  out += file_chunk(file, int(file.episodes.size()));
  for (const TrajectoryEpisode& ep : file.episodes) out += episode_chunk(ep);
  return out;
}

TrajectoryFile decode_trajectory(std::string_view bytes, bool verify_checksums) {
  if (bytes.size() < kTrajectoryMagic.size() ||
      bytes.substr(0, kTrajectoryMagic.size()) != kTrajectoryMagic) {
    throw TrajectoryError("byte 0: not an hns trajectory file (it must start with the magic \"HNSTRAJ\\n\")");
  }
  uint64_t pos = kTrajectoryMagic.size();
  TrajectoryFile file;
  const Chunk head = read_chunk(bytes, pos, "file header", verify_checksums);
  const Fields f(head.header, "byte 8 (file header)");
  if (!head.header.contains("format") || head.header["format"] != "hns-trajectory") {
    f.fail("format", "expected \"hns-trajectory\"" +
                         (head.header.contains("format") ? f.got(head.header["format"]) : ""));
  }
  const int64_t version = f.integer("version", 0, 1 << 30);
  if (version < 1 || version > kTrajectoryVersion) {
    f.fail("version", "this hns reads versions 1 to " + std::to_string(kTrajectoryVersion) + ", got " +
                          std::to_string(version) +
                          (version > kTrajectoryVersion ? " (a newer hns wrote it)" : ""));
  }
  if (version >= 3 && !head.header.contains("header_fnv1a64")) f.fail("header_fnv1a64", "missing");
  file.version = int(version);
  if (version == 1) {
    file.warnings.push_back(
        "a version 1 file: its episodes carry no checksum, so corruption inside their "
        "payload can only be caught by the range checks");
  } else if (version == 2) {
    file.warnings.push_back(
        "a version 2 file: its headers carry no checksum, so corruption inside them can only be caught by "
        "the range checks");
  }
  const int64_t episodes = f.integer("episodes", 0, 1 << 24);
  file.created_by = f.string("created_by");
  file.policy = f.string("policy");
  for (int64_t e = 0; e < episodes; ++e) {
    if (pos == bytes.size()) {
      throw TrajectoryError("byte " + std::to_string(pos) + ": the file ends after " + std::to_string(e) +
                            " of " + std::to_string(episodes) + " episodes (truncated file?)");
    }
    const std::string what = "episode " + std::to_string(e);
    const uint64_t start = pos;
    const Chunk c = read_chunk(bytes, pos, what, verify_checksums);
    if (version >= 3 && !c.header.contains("header_fnv1a64"))
      throw TrajectoryError("byte " + std::to_string(start) + " (" + what + "): \"header_fnv1a64\": missing");
    file.episodes.push_back(read_episode(bytes, c, "byte " + std::to_string(start) + " (" + what + ")",
                                         int(version), verify_checksums));
  }
  if (pos != bytes.size()) {
    throw TrajectoryError("byte " + std::to_string(pos) + ": " + std::to_string(bytes.size() - pos) +
                          " unexpected bytes after the last of the " + std::to_string(episodes) +
                          " episodes the file header announces");
  }
  return file;
}

std::string read_file_bytes(const std::string& path) {
  try {
    return ppo::read_regular_file(path, ppo::kMaxTrajectoryBytes, "");
  } catch (const ppo::FileError& e) {
    throw TrajectoryError(e.what());
  } catch (const std::system_error& e) {
    throw TrajectoryError(path + ": cannot read: " + e.code().message());
  }
}

TrajectoryFile read_trajectory(const std::string& path) {
  const std::string bytes = read_file_bytes(path);
  try {
    return decode_trajectory(bytes);
  } catch (const TrajectoryError& e) {
    throw TrajectoryError(path + ": " + e.what());
  }
}

TrajectoryWriter::TrajectoryWriter(const std::string& path, const TrajectoryFile& meta, int episodes)
    : path_(path), tmp_(path + ".tmp"), expected_(episodes) {
  ppo::check_replaceable(path_, "");
  const int fd = ppo::create_temp_file(tmp_);  // never writes through a link planted as PATH.tmp
  out_ = ::fdopen(fd, "wb");
  if (out_ == nullptr) {
    const int err = errno;
    ::close(fd);
    std::remove(tmp_.c_str());
    throw std::runtime_error("cannot write " + tmp_ + ": " + std::strerror(err));
  }
  // A constructor that throws runs no destructor: the file is closed and removed here.
  try {
    const std::string head = std::string(kTrajectoryMagic) + file_chunk(meta, episodes);
    if (std::fwrite(head.data(), 1, head.size(), out_) != head.size()) {
      throw std::runtime_error("cannot write " + tmp_ + ": " + std::strerror(errno));
    }
    bytes_ = head.size();
  } catch (...) {
    std::fclose(out_);
    out_ = nullptr;
    std::remove(tmp_.c_str());
    throw;
  }
}

TrajectoryWriter::~TrajectoryWriter() {
  if (out_ != nullptr) {
    std::fclose(out_);
    std::error_code ignored;
    std::filesystem::remove(tmp_, ignored);
  }
}

void TrajectoryWriter::add(const TrajectoryEpisode& episode) {
  if (written_ >= expected_) {
    throw std::logic_error("TrajectoryWriter: more than the " + std::to_string(expected_) +
                           " announced episodes");
  }
  const std::string chunk = episode_chunk(episode);
  if (std::fwrite(chunk.data(), 1, chunk.size(), out_) != chunk.size()) {
    throw std::runtime_error("cannot write " + tmp_ + ": " + std::strerror(errno));
  }
  bytes_ += chunk.size();
  ++written_;
}

uint64_t TrajectoryWriter::finish() {
  if (written_ != expected_) {
    throw std::logic_error("TrajectoryWriter: " + std::to_string(written_) + " of " +
                           std::to_string(expected_) + " announced episodes written");
  }
  // Flushed to the disk before the rename, so a crash leaves the old file or the whole new one.
  const bool flushed = std::fflush(out_) == 0 && ::fsync(::fileno(out_)) == 0;
  const bool closed = std::fclose(out_) == 0;
  out_ = nullptr;
  std::error_code ec;
  if (flushed && closed) std::filesystem::rename(tmp_, path_, ec);
  if (!flushed || !closed || ec) {
    const std::string reason = ec ? ec.message() : std::strerror(errno);
    std::error_code ignored;
    std::filesystem::remove(tmp_, ignored);
    throw std::runtime_error("cannot write " + path_ + ": " + reason);
  }
  return bytes_;
}

}  // namespace hns::replay
