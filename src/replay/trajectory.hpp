// Trajectory files: recorded hide-and-seek episodes for the replay viewer (docs/trajectory-format.md).
//
//   file    = magic "HNSTRAJ\n" (8 bytes), a file chunk, then one chunk per episode
//   chunk   = u32 little-endian JSON length L, L bytes of JSON (space-padded so that the payload starts on an
//             8-byte boundary), then `payload_bytes` bytes of typed blocks named in the JSON ("blocks")
//
// Frame t of an episode is the state after t env steps: frame 0 is the reset state, frame `horizon` the
// final state (an episode has horizon + 1 frames). Blocks are frame-major, little-endian.
#pragma once

#include <array>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace hns::replay {

// 2: episodes carry a checksum of their payload; 3: every header carries a checksum of itself too (1 and 2
// are still read).
inline constexpr int kTrajectoryVersion = 3;
// Bounds of the physically meaningful values a reader accepts (the simulator resets a world whose bodies
// leave the first two).
inline constexpr double kTrajectoryMaxXY = 200.0;    // m, |x| and |y| of every body
inline constexpr double kTrajectoryMaxZ = 100.0;     // m, |z|
inline constexpr double kTrajectoryMaxYaw = 4.0;     // rad, |yaw| (recorded in [-π, π])
inline constexpr double kTrajectoryMaxReward = 1e4;  // |reward| of one step
inline constexpr std::string_view kTrajectoryMagic{"HNSTRAJ\n", 8};
inline constexpr int kActionFields = 5;          // move x, move y, turn (bins 0..10), grab, lock (0/1)
inline constexpr int kTrajectoryLidarRays = 30;  // world-fixed rays, angle 2πk/30 from +x
inline constexpr double kLidarUnit = 1e-4;       // m per count of the u16 lidar block
// Reader limits: slots beyond these cannot be indexed by the i8 blocks (holding, locker).
inline constexpr int kTrajectoryMaxAgents = 64;
inline constexpr int kTrajectoryMaxObjects = 127;
inline constexpr int kTrajectoryMaxFrames = 1000001;

// A malformed trajectory file. The message says where (byte offset, episode, field or block) and what is
// wrong.
class TrajectoryError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Lock state of an object in a frame (the object_lock block).
enum LockState : uint8_t { kUnlocked = 0, kLockedByHiders = 1, kLockedBySeekers = 2 };

// One recorded episode: the scene (header) and per-frame blocks.
struct TrajectoryEpisode {
  // Header.
  std::string scene;   // preset (batch::kScenes)
  std::string layout;  // wall layout: quadrant, randomwalls, empty, var_tri
  uint64_t seed = 0;   // the run's seed; with env and episode it names the scene's random stream
  int env = 0;
  int episode = 0;
  int horizon = 0;           // env steps of the episode
  int prep_steps = 0;        // steps 1..prep_steps are preparation (seekers frozen, rewards 0)
  double step_time = 0.075;  // s of simulated time per env step
  int num_hiders = 0;        // agents 0..num_hiders-1 are hiders, the rest seekers
  int num_seekers = 0;
  int num_boxes = 0;  // objects: boxes first, then ramps
  int num_elongated = 0;
  int num_ramps = 0;
  int num_food = 0;  // food items (the food variants)
  bool outer_walls = true;
  std::vector<std::array<double, 6>> walls;  // static boxes: centre x, y, z, half extents x, y, z (m)
  // Static cylinders standing on the floor: axis x, y, radius, height (m).
  std::vector<std::array<double, 4>> cylinders;
  // Construction sites (blueprint) on the floor: centre x, y and edge (m); not physical.
  std::vector<std::array<double, 3>> sites;
  std::vector<std::array<double, 3>> box_sizes;     // full extents x, y, z (m), one per box
  std::array<double, 4> restrict_rect{0, 0, 0, 0};  // out-of-bounds rectangle x_min, y_min, x_max, y_max (m)
  double hider_return = 0;                          // summed mean hider reward over the episode
  double seeker_return = 0;                         // summed mean seeker reward
  int frames = 0;                                   // frames recorded (horizon + 1 for a whole episode)

  // Blocks, frame-major: index [frame][...]. A = agents, B = boxes, R = ramps, O = B + R.
  std::vector<float> agent_pose;      // x, y, z (m, centre), yaw (rad) (frames x A x 4)
  std::vector<float> box_pose;        // the same for boxes (frames x B x 4)
  std::vector<float> ramp_pose;       // ramps, bounding-box centre (frames x R x 4)
  std::vector<uint8_t> object_lock;   // LockState per object (frames x O)
  std::vector<int8_t> object_locker;  // agent that locked the object last, -1 never (frames x O)
  std::vector<int8_t> agent_holding;  // object the agent holds, -1 none (frames x A)
  std::vector<uint8_t> vis_agents;    // agent i sees agent j, diagonal 1 (frames x A x A)
  std::vector<uint8_t> vis_boxes;     // agent sees box (frames x A x B)
  std::vector<uint8_t> vis_ramps;     // agent sees ramp (frames x A x R)
  std::vector<uint16_t> lidar;        // distance in kLidarUnit (frames x A x 30)
  std::vector<float> reward;          // reward of the step that produced the frame, 0 at frame 0 (frames x A)
  std::vector<uint8_t> prep;          // 1 if the frame lies in the preparation phase (frames)
  std::vector<uint8_t> action;        // action of the step that produced the frame (frames x A x 5)
  std::vector<float> food;            // food items: x, y, z (m), units left (frames x F x 4)

  int num_agents() const { return num_hiders + num_seekers; }
  int num_objects() const { return num_boxes + num_ramps; }
  // Sizes every block for `n` frames, zero-filled (holding and locker -1).
  void resize(int n);
  bool operator==(const TrajectoryEpisode&) const = default;
};

// FNV-1a 64 of bytes as 16 hex digits: the "payload_fnv1a64" of episode headers (version 2 on) and, over a
// header's compact JSON without the key, the "header_fnv1a64" of every header (version 3).
std::string trajectory_checksum(std::string_view payload);

struct TrajectoryFile {
  int version = kTrajectoryVersion;   // as read (writers always write kTrajectoryVersion)
  std::vector<std::string> warnings;  // what a reader should tell the user (e.g. an unchecksummed old file)
  std::string created_by = "hns play";
  std::string policy = "random";  // random, or the checkpoint that chose the actions
  std::vector<TrajectoryEpisode> episodes;
  bool operator==(const TrajectoryFile&) const = default;
};

// The whole file in memory.
std::string encode_trajectory(const TrajectoryFile& file);
// Parses and checks everything (structure, header fields, block shapes, values); throws TrajectoryError.
// verify_checksums = false skips the payload checksums (the fuzzer's way past them); every other check runs.
TrajectoryFile decode_trajectory(std::string_view bytes, bool verify_checksums = true);
// The bytes of a file; throws TrajectoryError "PATH: cannot read: ..." if it cannot be read.
std::string read_file_bytes(const std::string& path);
// Reads and decodes a file; errors are prefixed with the path.
TrajectoryFile read_trajectory(const std::string& path);

// Streams episodes into `path` atomically: a temporary file beside it, renamed by finish(). If finish() is
// never reached (an error, fewer episodes than announced), the temporary file is removed and `path`
// untouched.
class TrajectoryWriter {
 public:
  // Opens the temporary file (throws std::runtime_error "cannot write ...") and writes the file chunk.
  TrajectoryWriter(const std::string& path, const TrajectoryFile& meta, int episodes);
  ~TrajectoryWriter();
  TrajectoryWriter(const TrajectoryWriter&) = delete;
  TrajectoryWriter& operator=(const TrajectoryWriter&) = delete;

  void add(const TrajectoryEpisode& episode);
  // Checks the announced count was written, flushes and renames. Returns the file size in bytes.
  uint64_t finish();

 private:
  std::string path_, tmp_;
  std::FILE* out_ = nullptr;
  int expected_ = 0, written_ = 0;
  uint64_t bytes_ = 0;
};

}  // namespace hns::replay
