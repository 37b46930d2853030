// Trajectory files: encode/decode round trip, the streaming writer, and clear errors for malformed files.
#include "replay/trajectory.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "physics/rng.hpp"

namespace hns::replay {
namespace {

using nlohmann::json;

// A valid episode with every block filled from a seeded stream.
TrajectoryEpisode make_episode(int hiders, int seekers, int boxes, int ramps, int frames, uint64_t seed) {
  TrajectoryEpisode ep;
  ep.scene = "quadrant";
  ep.layout = "quadrant";
  ep.seed = seed;
  ep.env = 3;
  ep.episode = 7;
  ep.horizon = frames - 1;
  ep.prep_steps = (frames - 1) / 3;
  ep.num_hiders = hiders;
  ep.num_seekers = seekers;
  ep.num_boxes = boxes;
  ep.num_elongated = boxes / 2;
  ep.num_ramps = ramps;
  ep.walls = {{3.0, 0.1, 2.0, 3.0, 0.05, 2.0}, {3.1, 1.5, 0.25, 0.05, 1.45, 0.25}};
  for (int b = 0; b < boxes; ++b) ep.box_sizes.push_back({0.5, b < ep.num_elongated ? 1.65 : 0.5, 0.5});
  ep.restrict_rect = {0.1, 0.1, 5.9, 5.9};
  ep.hider_return = -12.5;
  ep.seeker_return = 12.5;
  ep.resize(frames);
  physics::Rng rng(seed, 1, 2);
  const int a = ep.num_agents(), o = ep.num_objects();
  // Poses (x, y, z, yaw): positions around the arena, yaw in [-π, π].
  for (auto* poses : {&ep.agent_pose, &ep.box_pose, &ep.ramp_pose}) {
    for (size_t i = 0; i < poses->size(); ++i)
      (*poses)[i] = float(i % 4 == 3 ? rng.uniform(-3.14, 3.14) : rng.uniform(-1, 7));
  }
  for (uint8_t& v : ep.object_lock) v = uint8_t(rng.uniform_int(0, 3));
  for (int8_t& v : ep.object_locker) v = int8_t(rng.uniform_int(-1, a));
  for (int8_t& v : ep.agent_holding) v = int8_t(rng.uniform_int(-1, o));
  for (uint8_t& v : ep.vis_agents) v = uint8_t(rng.uniform_int(0, 2));
  for (uint8_t& v : ep.vis_boxes) v = uint8_t(rng.uniform_int(0, 2));
  for (uint8_t& v : ep.vis_ramps) v = uint8_t(rng.uniform_int(0, 2));
  for (uint16_t& v : ep.lidar) v = uint16_t(rng.uniform_int(0, 60001));
  for (float& v : ep.reward) v = float(rng.uniform_int(-1, 2));
  for (int t = 0; t < frames; ++t) ep.prep[t] = t <= ep.prep_steps ? 1 : 0;
  for (size_t i = 0; i < ep.action.size(); ++i)
    ep.action[i] = uint8_t(rng.uniform_int(0, i % 5 < 3 ? 11 : 2));
  return ep;
}

TrajectoryFile make_file() {
  TrajectoryFile f;
  f.created_by = "trajectory_test";
  f.policy = "random";
  f.episodes.push_back(make_episode(2, 2, 2, 1, 5, 11));
  f.episodes.push_back(make_episode(1, 3, 0, 0, 3, 12));  // no boxes, no ramps: empty blocks
  f.episodes.push_back(make_episode(3, 3, 9, 2, 4, 13));
  return f;
}

// The chunks of an encoded file, to edit headers and payloads in tests.
struct RawChunk {
  json header;
  std::string payload;
};
std::vector<RawChunk> split(const std::string& bytes) {
  std::vector<RawChunk> chunks;
  size_t pos = 8;
  while (pos < bytes.size()) {
    uint32_t len = 0;
    std::memcpy(&len, bytes.data() + pos, 4);
    RawChunk c;
    c.header = json::parse(bytes.substr(pos + 4, len));
    const size_t n = c.header["payload_bytes"].get<size_t>();
    c.payload = bytes.substr(pos + 4 + len, n);
    chunks.push_back(c);
    pos += 4 + len + n;
  }
  return chunks;
}
// Re-assembles chunks with correct padding (payload_bytes is kept as the header says) and, for an edited
// header or payload, matching checksums (so that a test reaches the check it aims at).
// `edit_text(index, text)`, if given, may rewrite a header's JSON text (to write what json cannot hold).
std::string join(const std::vector<RawChunk>& chunks,
                 const std::function<void(size_t, std::string&)>& edit_text = nullptr) {
  std::string out(kTrajectoryMagic);
  for (size_t index = 0; index < chunks.size(); ++index) {
    RawChunk c = chunks[index];
    if (c.header.contains("payload_fnv1a64")) c.header["payload_fnv1a64"] = trajectory_checksum(c.payload);
    if (c.header.contains(
            "header_fnv1a64")) {  // over the compact JSON without the key (docs/trajectory-format.md)
      json rest = c.header;
      rest.erase("header_fnv1a64");
      c.header["header_fnv1a64"] = trajectory_checksum(rest.dump());
    }
    std::string text = c.header.dump();
    if (edit_text) edit_text(index, text);
    while ((4 + text.size()) % 8 != 0) text += ' ';
    const uint32_t len = uint32_t(text.size());
    out.append(reinterpret_cast<const char*>(&len), 4);
    out += text;
    out += c.payload;
  }
  return out;
}

// Decoding `bytes` fails with a TrajectoryError whose message holds every fragment.
void expect_error(const std::string& bytes, const std::vector<std::string>& fragments) {
  try {
    decode_trajectory(bytes);
    ADD_FAILURE() << "decoded without error; expected: " << fragments.front();
  } catch (const TrajectoryError& e) {
    for (const std::string& f : fragments)
      EXPECT_NE(std::string(e.what()).find(f), std::string::npos) << e.what();
  }
}

// Edits chunk `index` (0 = file header) of a valid file and returns the bytes.
std::string edited(const std::function<void(RawChunk&)>& edit, size_t index) {
  std::vector<RawChunk> chunks = split(encode_trajectory(make_file()));
  edit(chunks.at(index));
  return join(chunks);
}

json& block(RawChunk& c, const std::string& name) {
  for (json& b : c.header["blocks"]) {
    if (b["name"] == name) return b;
  }
  throw std::runtime_error("no block " + name);
}

TEST(Trajectory, RoundTripIsExact) {
  const TrajectoryFile file = make_file();
  const std::string bytes = encode_trajectory(file);
  EXPECT_EQ(bytes.substr(0, 8), "HNSTRAJ\n");
  EXPECT_EQ(bytes.size() % 8, 0u);
  const TrajectoryFile back = decode_trajectory(bytes);
  EXPECT_EQ(back, file);
  EXPECT_EQ(encode_trajectory(back), bytes);
}

TEST(Trajectory, BlocksAreAlignedAndDocumented) {
  const std::string bytes = encode_trajectory(make_file());
  size_t pos = 8;
  for (const RawChunk& c : split(bytes)) {
    uint32_t len = 0;
    std::memcpy(&len, bytes.data() + pos, 4);
    EXPECT_EQ((pos + 4 + len) % 8, 0u) << "payload of the chunk at byte " << pos << " is not 8-byte aligned";
    if (c.header["kind"] == "episode") {
      EXPECT_EQ(c.header["blocks"].size(), 14u);
      for (const json& b : c.header["blocks"]) EXPECT_EQ(b["offset"].get<size_t>() % 8, 0u) << b.dump();
      EXPECT_EQ(c.header["version"], kTrajectoryVersion);
      EXPECT_TRUE(c.header.contains("walls"));
      EXPECT_TRUE(c.header.contains("box_sizes"));
    }
    pos += 4 + len + c.payload.size();
  }
}

TEST(Trajectory, WriterStreamsTheSameBytesAtomically) {
  // Per process: two test runs on one machine (two build trees) must not share the folder.
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("hns_trajectory_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "a.traj").string();
  std::filesystem::remove(path);
  const TrajectoryFile file = make_file();
  {
    TrajectoryWriter w(path, file, int(file.episodes.size()));
    for (const TrajectoryEpisode& ep : file.episodes) w.add(ep);
    EXPECT_FALSE(std::filesystem::exists(path)) << "visible before finish()";
    EXPECT_EQ(w.finish(), encode_trajectory(file).size());
  }
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  EXPECT_EQ(read_trajectory(path), file);

  // Abandoned or short writes leave neither the file nor the temporary behind.
  const std::string other = (dir / "b.traj").string();
  std::filesystem::remove(other);
  {
    TrajectoryWriter w(other, file, 2);
    w.add(file.episodes[0]);
    EXPECT_THROW(w.finish(), std::logic_error);
  }
  EXPECT_FALSE(std::filesystem::exists(other));
  EXPECT_FALSE(std::filesystem::exists(other + ".tmp"));
  EXPECT_THROW(TrajectoryWriter((dir / "missing" / "c.traj").string(), file, 1), std::runtime_error);
  std::filesystem::remove_all(dir);
}

TEST(Trajectory, UnreadableFileNamesThePath) {
  try {
    read_trajectory("/nonexistent/dir/x.traj");
    FAIL();
  } catch (const TrajectoryError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/x.traj: cannot read"), std::string::npos)
        << e.what();
  }
}

TEST(TrajectoryErrors, MagicAndFileHeader) {
  expect_error("", {"byte 0", "not an hns trajectory"});
  expect_error("GIF89a..........", {"byte 0", "magic"});
  expect_error(edited([](RawChunk& c) { c.header["version"] = 4; }, 0),
               {"file header", "\"version\"", "reads versions 1 to 3", "newer"});
  expect_error(edited([](RawChunk& c) { c.header["format"] = "other"; }, 0), {"file header", "\"format\""});
  expect_error(edited([](RawChunk& c) { c.header["episodes"] = 4; }, 0),
               {"ends after 3 of 4 episodes", "truncated"});
  expect_error(edited([](RawChunk& c) { c.header["episodes"] = 2; }, 0), {"unexpected bytes", "2 episodes"});
  expect_error(edited([](RawChunk& c) { c.header.erase("policy"); }, 0), {"\"policy\": missing"});
}

TEST(TrajectoryErrors, EpisodeHeaderFields) {
  expect_error(edited([](RawChunk& c) { c.header["num_boxes"] = "two"; }, 2),
               {"episode 1", "\"num_boxes\"", "expected an integer", "\"two\""});
  expect_error(edited([](RawChunk& c) { c.header.erase("horizon"); }, 1),
               {"episode 0", "\"horizon\": missing"});
  expect_error(edited([](RawChunk& c) { c.header["version"] = 7; }, 3), {"episode 2", "\"version\""});
  expect_error(edited([](RawChunk& c) { c.header["frames"] = 100; }, 1), {"\"frames\"", "[1, 5]"});
  expect_error(edited([](RawChunk& c) { c.header["box_sizes"].erase(0); }, 1),
               {"\"box_sizes\"", "expected 2 entries"});
  expect_error(edited(
                   [](RawChunk& c) {
                     c.header["walls"][1] = json::array({1, 2, 3});
                   },
                   1),
               {"\"walls\"", "entry 1", "6 numbers"});
  expect_error(edited(
                   [](RawChunk& c) {
                     c.header["num_hiders"] = 0;
                     c.header["num_seekers"] = 0;
                   },
                   1),
               {"at least one agent"});
  expect_error(edited([](RawChunk& c) { c.header["kind"] = "file"; }, 1), {"\"kind\"", "\"episode\""});
  // Geometry no arena has: a wall 1e300 m away, a site far out, a box size beyond any body.
  expect_error(edited([](RawChunk& c) { c.header["walls"][0][0] = 1e300; }, 1),
               {"episode 0", "\"walls\"", "entry 0", "beyond 200"});
  expect_error(edited([](RawChunk& c) { c.header["walls"][1][5] = 1000.0; }, 1),
               {"\"walls\"", "entry 1", "beyond 100"});
  expect_error(edited([](RawChunk& c) { c.header["box_sizes"][0][0] = 5000.0; }, 1),
               {"episode 0", "\"box_sizes\"", "beyond 200"});
  expect_error(edited([](RawChunk& c) { c.header["restrict_rect"][2] = -1e9; }, 1), {"\"restrict_rect\""});
  // JSON nested past any header's needs (70,000 levels overflowed the parser's stack before).
  expect_error(edited(
                   [](RawChunk& c) {
                     json deep = json::array();
                     for (int i = 0; i < 65; ++i) deep = json::array({deep});
                     c.header["zz"] = deep;
                   },
                   1),
               {"episode 0", "more than 64 levels deep"});
  // The pages show the scene and layout names: only hns's own are read, never markup from a file.
  expect_error(edited([](RawChunk& c) { c.header["scene"] = "<img src=x onerror=alert(1)>"; }, 1),
               {"episode 0", "\"scene\"", "is not a scene of hns"});
  expect_error(edited([](RawChunk& c) { c.header["layout"] = "<b>quadrant</b>"; }, 2),
               {"episode 1", "\"layout\"", "is not a layout of hns"});
}

// Every single-bit flip in a header (its length and its JSON text) is caught or changes nothing that is
// read: headers carry their own checksum (version 3), so a flip that keeps the JSON valid is caught by it.
TEST(TrajectoryErrors, EveryHeaderBitFlipIsCaught) {
  const std::string bytes = encode_trajectory(make_file());
  const std::string clean = encode_trajectory(decode_trajectory(bytes));
  // The file header and the first episode's header: [8, end of that JSON text).
  uint32_t file_len = 0, ep_len = 0;
  std::memcpy(&file_len, bytes.data() + 8, 4);
  const size_t ep_at = 8 + 4 + file_len;
  std::memcpy(&ep_len, bytes.data() + ep_at, 4);
  int caught = 0, silent = 0;
  for (const auto& [begin, end] : {std::pair<size_t, size_t>{8, ep_at}, {ep_at, ep_at + 4 + ep_len}}) {
    for (size_t i = begin; i < end; ++i) {
      for (int bit = 0; bit < 8; ++bit) {
        std::string flipped = bytes;
        flipped[i] = char(flipped[i] ^ (1 << bit));
        try {
          const TrajectoryFile f = decode_trajectory(flipped);
          if (encode_trajectory(f) != clean) {
            ++silent;
            ADD_FAILURE() << "byte " << i << " bit " << bit << " changed what is read without an error";
          }
        } catch (const TrajectoryError&) {
          ++caught;
        }
      }
    }
  }
  EXPECT_EQ(silent, 0);
  EXPECT_GT(caught, 8 * 1000);
  // A version 3 header without its checksum is refused, and so is one whose checksum is not a string.
  expect_error(edited([](RawChunk& c) { c.header.erase("header_fnv1a64"); }, 1),
               {"episode 0", "\"header_fnv1a64\": missing"});
  expect_error(edited([](RawChunk& c) { c.header.erase("header_fnv1a64"); }, 0),
               {"\"header_fnv1a64\": missing"});
  std::vector<RawChunk> chunks = split(bytes);
  chunks[1].header["seed"] = 12345;  // re-summed by join ...
  std::string resummed = join(chunks);
  const size_t at = resummed.find("\"seed\":12345");
  ASSERT_NE(at, std::string::npos);
  resummed.replace(at, 12, "\"seed\":12346");  // ... then changed: caught
  expect_error(resummed, {"episode 0", "\"header_fnv1a64\"", "a corrupt file"});
}

TEST(TrajectoryErrors, Blocks) {
  expect_error(edited([](RawChunk& c) { block(c, "agent_pose")["dtype"] = "u8"; }, 1),
               {"episode 0", "block \"agent_pose\"", "\"dtype\"", "f32"});
  expect_error(edited([](RawChunk& c) { block(c, "vis_boxes")["shape"][2] = 3; }, 1),
               {"block \"vis_boxes\"", "\"shape\"", "expected [5,4,2]", "frames x agents x boxes"});
  expect_error(edited(
                   [](RawChunk& c) {
                     json& blocks = c.header["blocks"];
                     for (size_t i = 0; i < blocks.size(); ++i) {
                       if (blocks[i]["name"] == "lidar") blocks.erase(i);
                     }
                   },
                   1),
               {"block \"lidar\": missing"});
  expect_error(edited([](RawChunk& c) { c.header["blocks"].push_back(c.header["blocks"][0]); }, 1),
               {"\"blocks\"", "appears twice"});
  expect_error(edited([](RawChunk& c) { block(c, "action")["offset"] = 1 << 20; }, 1),
               {"block \"action\"", "run past the payload"});
  expect_error(
      edited([](RawChunk& c) { block(c, "reward")["offset"] = block(c, "reward")["offset"].get<int>() + 2; },
             1),
      {"block \"reward\"", "\"offset\"", "not a multiple of 8"});
  // Unknown blocks are ignored (readers of later minor additions).
  const std::string extra = edited(
      [](RawChunk& c) {
        c.header["blocks"].push_back({{"name", "future"}});
      },
      1);
  EXPECT_EQ(decode_trajectory(extra), make_file());
}

TEST(TrajectoryErrors, Values) {
  // Overwrites element `index` of block `name` in episode 0 with the bytes of `value`.
  auto poke = [](const std::string& name, size_t index, auto value) {
    return edited(
        [&](RawChunk& c) {
          const size_t at = block(c, name)["offset"].get<size_t>() + index * sizeof(value);
          std::memcpy(c.payload.data() + at, &value, sizeof(value));
        },
        1);
  };
  // Episode 0: 4 agents, 2 boxes, 1 ramp, 5 frames.
  expect_error(poke("agent_pose", 16 + 5, std::numeric_limits<float>::quiet_NaN()),
               {"episode 0", "block \"agent_pose\"", "frame 1, element 5", "finite"});
  expect_error(poke("vis_agents", 3, uint8_t(2)),
               {"block \"vis_agents\"", "frame 0, element 3", "value 2", "0 or 1"});
  expect_error(poke("agent_holding", 4, int8_t(3)), {"block \"agent_holding\"", "frame 1", "object index"});
  expect_error(poke("object_lock", 0, uint8_t(3)), {"block \"object_lock\"", "value 3"});
  expect_error(poke("object_locker", 0, int8_t(4)), {"block \"object_locker\"", "agent index"});
  expect_error(poke("action", 20 + 5 * 2 + 1, uint8_t(11)),
               {"block \"action\"", "frame 1, agent 2, field 1", "0..10"});
  expect_error(poke("action", 3, uint8_t(2)), {"block \"action\"", "field 3", "0..1"});
  expect_error(poke("reward", 0, std::numeric_limits<float>::infinity()), {"block \"reward\"", "finite"});
}

// The shelter task's cylinder travels in the episode header; files without the field (written before it
// existed) read as having none; a cylinder without size is refused.
TEST(Trajectory, CylindersRoundTripAreOptionalAndChecked) {
  TrajectoryFile file;
  file.episodes.push_back(make_episode(1, 0, 2, 0, 5, 11));
  file.episodes[0].scene = "shelter";
  file.episodes[0].cylinders = {{3.0, 2.9, 0.8, 0.5}};
  const std::string bytes = encode_trajectory(file);
  EXPECT_EQ(decode_trajectory(bytes), file);
  file.episodes[0].cylinders.clear();
  const std::string none = encode_trajectory(file);
  std::vector<RawChunk> chunks = split(none);
  ASSERT_TRUE(chunks.at(1).header.contains("cylinders"));
  chunks.at(1).header.erase("cylinders");
  const std::string dropped = join(chunks);
  EXPECT_TRUE(decode_trajectory(dropped).episodes[0].cylinders.empty());
  file.episodes[0].cylinders = {{3.0, 2.9, 0.0, 0.5}};
  expect_error(encode_trajectory(file), {"field \"cylinders\"", "radius or height"});
}

// Blueprint's construction sites travel in the header and the food variants' items in a block of their
// own; files written before either existed (no "sites", no "num_food", no "food" block) read as having none;
// a site without size or an item with negative units is refused.
TEST(Trajectory, SitesAndFoodRoundTripAreOptionalAndChecked) {
  TrajectoryFile file;
  file.episodes.push_back(make_episode(2, 1, 2, 0, 4, 14));
  TrajectoryEpisode& ep = file.episodes[0];
  ep.scene = "dynamic-food";
  ep.sites = {{2.0, 3.0, 0.5}};
  ep.num_food = 2;
  ep.food.assign(size_t(ep.frames) * 2 * 4, 0.0f);
  for (size_t i = 0; i < ep.food.size(); ++i)
    ep.food[i] = float(i % 4 == 3 ? 40 - int(i / 8) : 2.5 + 0.01 * i);
  const std::string bytes = encode_trajectory(file);
  EXPECT_EQ(decode_trajectory(bytes), file);

  ep.sites.clear();
  ep.num_food = 0;
  ep.food.clear();
  std::vector<RawChunk> chunks = split(encode_trajectory(file));
  json& h = chunks.at(1).header;
  ASSERT_TRUE(h.contains("sites") && h.contains("num_food"));
  h.erase("sites");
  h.erase("num_food");
  json kept = json::array();
  for (const json& b : h["blocks"])
    if (b["name"] != "food") kept.push_back(b);
  ASSERT_EQ(kept.size(), h["blocks"].size() - 1);
  h["blocks"] = kept;
  const TrajectoryEpisode old = decode_trajectory(join(chunks)).episodes[0];
  EXPECT_TRUE(old.sites.empty());
  EXPECT_EQ(old.num_food, 0);
  EXPECT_TRUE(old.food.empty());

  ep.sites = {{2.0, 3.0, 0.0}};
  expect_error(encode_trajectory(file), {"field \"sites\"", "edge <= 0"});
  ep.sites.clear();
  ep.num_food = 1;
  ep.food.assign(size_t(ep.frames) * 4, 1.0f);
  ep.food[7] = -1.0f;
  expect_error(encode_trajectory(file), {"block \"food\"", "frame 1", "units left"});
}

// Version 2 episodes carry a checksum of their payload: any flipped payload byte is refused, naming it.
TEST(TrajectoryErrors, PayloadChecksum) {
  const std::string good = encode_trajectory(make_file());
  const std::vector<RawChunk> chunks = split(good);
  // The payload of episode 0 starts where its chunk's JSON ends.
  const size_t start = 8 + 4 + chunks[0].header.dump().size();
  size_t payload_at = good.find(chunks[1].payload, start);
  ASSERT_NE(payload_at, std::string::npos);
  physics::Rng rng(5, 0, 0);
  for (int trial = 0; trial < 200; ++trial) {
    std::string bad = good;
    const size_t at = payload_at + size_t(rng.uniform_int(0, int(chunks[1].payload.size())));
    bad[at] = char(bad[at] ^ (1 << rng.uniform_int(0, 8)));
    expect_error(bad, {"episode 0", "payload_fnv1a64", "corrupt"});
  }
}

// A version 1 file (no checksum) is still read, with a warning; its values are range checked, so a box
// flung to z = -4.6e18 m is refused.
TEST(TrajectoryErrors, VersionOneIsReadWithAWarningAndRangeChecked) {
  auto as_version_one = [](RawChunk& c) {
    c.header["version"] = 1;
    c.header.erase("payload_fnv1a64");
  };
  std::vector<RawChunk> chunks = split(encode_trajectory(make_file()));
  for (RawChunk& c : chunks) as_version_one(c);
  const TrajectoryFile old = decode_trajectory(join(chunks));
  EXPECT_EQ(old.version, 1);
  ASSERT_EQ(old.warnings.size(), 1u);
  EXPECT_NE(old.warnings[0].find("no checksum"), std::string::npos);
  EXPECT_EQ(old.episodes, make_file().episodes);
  const float far = -4.6e18f;
  const size_t z_of_box1 = 4 + 2;  // frame 0, box 1, element z
  std::memcpy(chunks[1].payload.data() + block(chunks[1], "box_pose")["offset"].get<size_t>() +
                  z_of_box1 * sizeof(float),
              &far, sizeof far);
  expect_error(join(chunks), {"episode 0", "block \"box_pose\"", "element 6", "z within ±100 m"});
  const TrajectoryFile fresh = decode_trajectory(encode_trajectory(make_file()));
  EXPECT_EQ(fresh.version, kTrajectoryVersion);
  EXPECT_TRUE(fresh.warnings.empty());
}

TEST(TrajectoryErrors, StructureAndTruncation) {
  const std::string good = encode_trajectory(make_file());
  // Every proper prefix fails with a TrajectoryError, never a crash or a partial result.
  for (size_t n = 0; n < good.size(); n += (n < 200 || good.size() - n < 200) ? 1 : 13) {
    EXPECT_THROW(decode_trajectory(std::string_view(good).substr(0, n)), TrajectoryError) << "prefix " << n;
  }
  expect_error(good.substr(0, good.size() - 8), {"truncated"});
  expect_error(good + "x", {"unexpected bytes"});
  // A header that is not JSON, or not padded to 8 bytes.
  std::string bad_json = good;
  bad_json[8 + 4] = '[';
  expect_error(bad_json, {"byte 8 (file header)", "not valid JSON"});
  // Well-formed JSON with a number beyond a double's range (the JSON library raises out_of_range there,
  // not parse_error): found by tools/fuzz in CI, where it ended the process.
  for (const size_t index : {size_t(0), size_t(2)}) {
    std::vector<RawChunk> chunks = split(good);
    chunks[index].header["overflow"] = 12345;
    const std::string bytes = join(chunks, [&](size_t i, std::string& text) {
      if (i == index) text.replace(text.find("12345"), 5, "1e999");
    });
    expect_error(bytes, {index == 0 ? "byte 8 (file header)" : "(episode 1)", "not valid JSON", "1e999"});
  }
  std::string text = split(good)[0].header.dump();
  if ((4 + text.size()) % 8 == 0) text += ' ';
  const uint32_t len = uint32_t(text.size());
  std::string unpadded(kTrajectoryMagic);
  unpadded.append(reinterpret_cast<const char*>(&len), 4);
  unpadded += text;
  expect_error(unpadded, {"unaligned"});
}

TEST(TrajectoryErrors, CorruptedBytesNeverCrash) {
  const std::string good = encode_trajectory(make_file());
  physics::Rng rng(99, 0, 0);
  int rejected = 0;
  for (int trial = 0; trial < 400; ++trial) {
    std::string bad = good;
    for (int k = 0; k < 3; ++k) bad[rng.uniform_int(0, int(bad.size()))] = char(rng.uniform_int(0, 256));
    try {
      decode_trajectory(bad);
    } catch (const TrajectoryError&) {
      ++rejected;
    }
  }
  EXPECT_GT(rejected, 0);
}

}  // namespace
}  // namespace hns::replay
