// Trajectory files, metrics rows and stage detection, and recordings of whole episodes (hns.read_trajectory,
// hns.record and the helpers behind hns.read_metrics and hns.detect_stages).
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "batch/host.hpp"
#include "common.hpp"
#include "ppo/atomic_file.hpp"
#include "ppo/policy.hpp"
#include "replay/metrics.hpp"
#include "replay/play.hpp"
#include "replay/recorder.hpp"
#include "replay/stages.hpp"
#include "replay/trajectory.hpp"

namespace hns::python {
namespace {

template <class T>
py::array_t<T> block(const std::vector<T>& v, const Shape& shape) {
  py::array_t<T> a(shape);
  if (!v.empty()) std::memcpy(a.mutable_data(), v.data(), v.size() * sizeof(T));
  return a;
}

py::dict episode_dict(const replay::TrajectoryEpisode& ep) {
  py::dict d;
  d["scene"] = ep.scene;
  d["layout"] = ep.layout;
  d["seed"] = ep.seed;
  d["env"] = ep.env;
  d["episode"] = ep.episode;
  d["horizon"] = ep.horizon;
  d["prep_steps"] = ep.prep_steps;
  d["step_time"] = ep.step_time;
  d["num_hiders"] = ep.num_hiders;
  d["num_seekers"] = ep.num_seekers;
  d["num_boxes"] = ep.num_boxes;
  d["num_elongated"] = ep.num_elongated;
  d["num_ramps"] = ep.num_ramps;
  d["num_food"] = ep.num_food;
  d["outer_walls"] = ep.outer_walls;
  d["hider_return"] = ep.hider_return;
  d["seeker_return"] = ep.seeker_return;
  d["frames"] = ep.frames;
  py::array_t<double> walls(Shape{py::ssize_t(ep.walls.size()), 6});
  for (size_t i = 0; i < ep.walls.size(); ++i)
    for (int k = 0; k < 6; ++k) walls.mutable_at(py::ssize_t(i), k) = ep.walls[i][size_t(k)];
  d["walls"] = walls;
  py::array_t<double> cylinders(Shape{py::ssize_t(ep.cylinders.size()), 4});
  for (size_t i = 0; i < ep.cylinders.size(); ++i)
    for (int k = 0; k < 4; ++k) cylinders.mutable_at(py::ssize_t(i), k) = ep.cylinders[i][size_t(k)];
  d["cylinders"] = cylinders;
  py::array_t<double> sites(Shape{py::ssize_t(ep.sites.size()), 3});
  for (size_t i = 0; i < ep.sites.size(); ++i)
    for (int k = 0; k < 3; ++k) sites.mutable_at(py::ssize_t(i), k) = ep.sites[i][size_t(k)];
  d["sites"] = sites;
  py::array_t<double> sizes(Shape{py::ssize_t(ep.box_sizes.size()), 3});
  for (size_t i = 0; i < ep.box_sizes.size(); ++i)
    for (int k = 0; k < 3; ++k) sizes.mutable_at(py::ssize_t(i), k) = ep.box_sizes[i][size_t(k)];
  d["box_sizes"] = sizes;
  py::array_t<double> rect(4);
  for (int k = 0; k < 4; ++k) rect.mutable_at(k) = ep.restrict_rect[size_t(k)];
  d["restrict_rect"] = rect;

  const py::ssize_t F = ep.frames, A = ep.num_agents(), B = ep.num_boxes, R = ep.num_ramps, O = B + R;
  d["agent_pose"] = block(ep.agent_pose, {F, A, 4});
  d["box_pose"] = block(ep.box_pose, {F, B, 4});
  d["ramp_pose"] = block(ep.ramp_pose, {F, R, 4});
  d["object_lock"] = block(ep.object_lock, {F, O});
  d["object_locker"] = block(ep.object_locker, {F, O});
  d["agent_holding"] = block(ep.agent_holding, {F, A});
  d["vis_agents"] = block(ep.vis_agents, {F, A, A});
  d["vis_boxes"] = block(ep.vis_boxes, {F, A, B});
  d["vis_ramps"] = block(ep.vis_ramps, {F, A, R});
  py::array_t<float> lidar(Shape{F, A, replay::kTrajectoryLidarRays});
  for (size_t i = 0; i < ep.lidar.size(); ++i)
    lidar.mutable_data()[i] = float(ep.lidar[i] * replay::kLidarUnit);
  d["lidar"] = lidar;
  d["reward"] = block(ep.reward, {F, A});
  d["prep"] = block(ep.prep, {F});
  d["action"] = block(ep.action, {F, A, replay::kActionFields});
  d["food"] = block(ep.food, {F, py::ssize_t(ep.num_food), 4});
  return d;
}

py::dict read_trajectory(const py::object& path_arg) {
  const std::string path = path_from(path_arg, "path");
  if (!std::filesystem::exists(path)) raise(PyExc_FileNotFoundError, path + ": no such file");
  replay::TrajectoryFile file;
  {
    py::gil_scoped_release release;
    file = replay::read_trajectory(path);
  }
  py::dict d;
  d["version"] = file.version;
  d["created_by"] = file.created_by;
  d["policy"] = file.policy;
  d["warnings"] = file.warnings;
  py::list episodes;
  for (const replay::TrajectoryEpisode& ep : file.episodes) episodes.append(episode_dict(ep));
  d["episodes"] = episodes;
  return d;
}

std::string read_metrics_json(const py::object& path_arg) {
  const std::string path = path_from(path_arg, "path");
  if (!std::filesystem::exists(path)) raise(PyExc_FileNotFoundError, path + ": no such file");
  std::string text;
  try {
    text = ppo::read_regular_file(path, ppo::kMaxMetricsBytes, "");
  } catch (const std::exception& e) {
    raise(PyExc_OSError, e.what());
  }
  try {
    return replay::read_metrics_jsonl(text).json;
  } catch (const replay::MetricsError& e) {
    raise(PyExc_ValueError, path + ":" + std::to_string(e.line) + ": " + e.what());
  }
}

// replay::detect_stages over metrics rows given as a JSON array (hns.detect_stages serialises its rows).
std::string detect_stages_json(const std::string& rows_json, const std::string& scene) {
  return replay::detect_stages(replay::MetricsRows{rows_json, 0}, scene).to_json();
}

// Records whole episodes into a trajectory file, as `hns play` does (the same bytes for the same arguments,
// but for the file's created_by).
py::dict record(const py::object& path_arg, const std::string& scene, const py::object& checkpoint_arg,
                int episodes, int envs, int threads, const py::object& seed_arg, std::optional<int> hiders,
                std::optional<int> seekers, std::optional<int> boxes, std::optional<int> ramps) {
  const std::string path = path_from(path_arg, "path");
  const std::filesystem::path folder = std::filesystem::path(path).parent_path();
  if (!folder.empty() && !std::filesystem::is_directory(folder)) {
    raise(PyExc_FileNotFoundError, "path: " + path + ": its folder does not exist");
  }
  if (std::filesystem::is_directory(path)) raise(PyExc_IsADirectoryError, "path: " + path + " is a folder");
  const uint64_t seed = seed_from(seed_arg);
  if (episodes < 1 || episodes > 100000) {
    raise(PyExc_ValueError, "episodes = " + std::to_string(episodes) + " is invalid: must be in [1, 100000]");
  }
  if (envs < 1 || envs > 4096) {
    raise(PyExc_ValueError, "envs = " + std::to_string(envs) + " is invalid: must be in [1, 4096]");
  }
  if (threads < 0) {
    raise(PyExc_ValueError,
          "threads = " + std::to_string(threads) + " is invalid: must be >= 0 (0 = every hardware thread)");
  }
  std::unique_ptr<ppo::Policy> policy;
  std::string checkpoint;
  if (!checkpoint_arg.is_none()) {
    checkpoint = path_from(checkpoint_arg, "checkpoint");
    if (!std::filesystem::exists(checkpoint)) raise(PyExc_FileNotFoundError, checkpoint + ": no such file");
    std::error_code ec;
    if (std::filesystem::equivalent(path, checkpoint, ec)) {
      raise(PyExc_ValueError,
            "path: " + path + " is the checkpoint this recording plays; choose another file");
    }
    try {
      policy = ppo::Policy::from_checkpoint(checkpoint, seed);
    } catch (const std::runtime_error& e) {
      raise(PyExc_ValueError, std::string("checkpoint: ") + e.what());
    }
  }
  const replay::RecordConfig config =
      replay::play_config(scene, policy.get(), batch::CountOverrides{hiders, seekers, boxes, ramps}, episodes,
                          envs, batch::usable_threads(threads), seed);
  batch::check_memory("envs = " + std::to_string(envs), config.game.estimated_bytes());
  replay::TrajectoryFile meta;
  meta.created_by = "hns.record";
  meta.policy = policy ? checkpoint : "random";
  replay::RecordSummary summary;
  uint64_t bytes = 0;
  {
    py::gil_scoped_release release;
    replay::TrajectoryWriter writer(path, meta, episodes);
    summary = replay::record_episodes(config, replay::play_actions(policy.get(), seed),
                                      [&](const replay::TrajectoryEpisode& ep) { writer.add(ep); });
    bytes = writer.finish();
  }
  py::dict d;
  d["scene"] = config.scene;
  d["recorded"] = summary.recorded;
  d["discarded"] = summary.discarded;
  d["bytes"] = bytes;
  return d;
}

}  // namespace

void bind_recordings(py::module_& m) {
  // TrajectoryError (a ValueError) with the message kept even where it quotes a damaged file's bytes.
  static py::exception<hns::replay::TrajectoryError> trajectory_error(m, "TrajectoryError", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const hns::replay::TrajectoryError& e) {
      set_error(trajectory_error.ptr(), e.what());
    }
  });

  m.def("read_trajectory", &read_trajectory, py::arg("path"),
        "A trajectory file (hns play, hns train's replay.traj) as a dict of headers and numpy blocks.");
  m.def("_read_metrics_json", &read_metrics_json, py::arg("path"));
  m.def("_detect_stages_json", &detect_stages_json, py::arg("rows_json"), py::arg("scene"));
  m.def("record", &record, py::arg("path"), py::arg("scene") = "", py::arg("checkpoint") = py::none(),
        py::arg("episodes") = 1, py::arg("envs") = 1, py::arg("threads") = 1, py::arg("seed") = py::int_(1),
        py::arg("hiders") = py::none(), py::arg("seekers") = py::none(), py::arg("boxes") = py::none(),
        py::arg("ramps") = py::none(),
        "Records whole episodes (random actions, or a checkpoint's policy) into a trajectory file, as `hns "
        "play` does; returns what was recorded. The GIL is released while it plays.");
}

}  // namespace hns::python
