// The compiled part of the Python package `hns` (hns/_hns*.so; python/hns/__init__.py is its front):
// the batch simulator as a Gymnasium-style vector environment whose arrays view the batch's own buffers,
// trained policies, and the trajectory and metrics readers. Thin by design: argument checks and array
// plumbing here, the work in the libraries (hns_batch, hns_ppo, hns_replay). docs/python.md is the manual.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "batch/batch_sim.hpp"
#include "batch/host.hpp"
#include "physics/presets.hpp"
#include "physics/scene.hpp"
#include "ppo/atomic_file.hpp"
#include "ppo/batch_obs.hpp"
#include "ppo/policy.hpp"
#include "replay/metrics.hpp"
#include "replay/play.hpp"
#include "replay/recorder.hpp"
#include "replay/render.hpp"
#include "replay/stages.hpp"
#include "replay/trajectory.hpp"

namespace py = pybind11;

namespace hns::python {
namespace {

namespace phys = hns::physics;
using Shape = std::vector<py::ssize_t>;

// The fields of a step's observation dict: the policy's and the value net's inputs, and the two per-env
// counters a policy needs (step_count 0 starts an episode: LSTM states zeroed; the episode number seeds its
// sampling stream).
constexpr const char* kObsFields[] = {
    "obs_self",         "lidar",      "obs_agents", "obs_boxes",         "obs_ramps",
    "mask_agents",      "mask_boxes", "mask_ramps", "value_mask_agents", "value_mask_boxes",
    "value_mask_ramps", "step_count", "episode"};
// ... and, in scenes with the fourth entity type (blueprint's construction sites, the food variants' items),
// these.
constexpr const char* kSiteObsFields[] = {"obs_sites", "mask_sites", "value_mask_sites"};

// Per-env dimensions of every batch field (BatchState, HNS_BATCH_FIELDS): a dimension of size 1 stays an
// axis (lockbox's one agent still has an agent axis); per-env scalars have none.
Shape field_dims(const std::string& name, size_t count, const batch::Layout& L) {
  const py::ssize_t A = L.max_agents, B = L.max_boxes, R = L.max_ramps, O = L.others, C = L.max_sites,
                    CS = L.construction_sites, FD = L.max_food;
  const struct {
    const char* name;
    Shape dims;
  } table[] = {
      {"agent_pos", {A, 3}},
      {"agent_rot", {A, 2}},
      {"agent_vel", {A, 3}},
      {"agent_angvel", {A}},
      {"agent_exists", {A}},
      {"agent_hider", {A}},
      {"box_pos", {B, 3}},
      {"box_rot", {B, 2}},
      {"box_vel", {B, 3}},
      {"box_angvel", {B}},
      {"box_size", {B, 3}},
      {"box_exists", {B}},
      {"box_locked", {B}},
      {"box_locker", {B}},
      {"ramp_pos", {R, 3}},
      {"ramp_rot", {R, 2}},
      {"ramp_vel", {R, 3}},
      {"ramp_angvel", {R}},
      {"ramp_exists", {R}},
      {"ramp_locked", {R}},
      {"ramp_locker", {R}},
      {"site_pos", {CS, 3}},
      {"site_exists", {CS}},
      {"food_pos", {FD, 3}},
      {"food_health", {FD}},
      {"food_respawn", {FD}},
      {"food_exists", {FD}},
      {"food_eat_ok", {A, FD}},
      {"food_eaten", {A}},
      {"vis_food", {A, FD}},
      {"num_walls", {}},
      {"vis_agents", {A, A}},
      {"vis_boxes", {A, B}},
      {"vis_ramps", {A, R}},
      {"lidar", {A, batch::Layout::kLidar}},
      {"reward", {A}},
      {"done", {}},
      {"step_count", {}},
      {"episode", {}},
      {"box_pos_start", {B, 3}},
      {"ramp_pos_start", {R, 3}},
      {"agent_pos_start", {A, 3}},
      {"stat_prep", {batch::Layout::kPrepStats}},
      {"stat_run", {batch::Layout::kRunStats}},
      {"episode_return", {2}},
      {"task_target", {}},
      {"task_dist", {}},
      {"task_spawn", {2}},
      {"task_locked", {B}},
      {"task_complete", {}},
      {"obs_self", {A, batch::Layout::kSelfFeatures}},
      {"obs_agents", {A, O, batch::Layout::kAgentFeatures}},
      {"mask_agents", {A, O}},
      {"value_mask_agents", {A, O}},
      {"obs_boxes", {A, B, batch::Layout::kBoxFeatures}},
      {"mask_boxes", {A, B}},
      {"value_mask_boxes", {A, B}},
      {"obs_ramps", {A, R, batch::Layout::kRampFeatures}},
      {"mask_ramps", {A, R}},
      {"value_mask_ramps", {A, R}},
      {"obs_sites", {A, C, L.site_features}},
      {"mask_sites", {A, C}},
      {"value_mask_sites", {A, C}},
  };
  Shape dims;
  bool found = false;
  if (name.rfind("shape_box_", 0) == 0) {
    dims = {L.shape_boxes}, found = true;
  } else if (name.rfind("shape_wedge_", 0) == 0) {
    dims = {L.shape_wedges}, found = true;
  } else if (name.rfind("shape_sphere_", 0) == 0) {
    dims = {L.shape_spheres}, found = true;
  } else if (name.rfind("shape_cyl_", 0) == 0) {
    dims = {L.shape_cylinders}, found = true;
  }
  for (const auto& row : table) {
    if (name == row.name) dims = row.dims, found = true;
  }
  size_t product = 1;
  for (py::ssize_t d : dims) product *= size_t(d);
  if (!found || product != count) {
    throw std::logic_error("hns: the shape table of the Python module does not describe batch field " + name);
  }
  return dims;
}

// A read-only array over `data` (C order) kept alive by `owner`; `as_bool` views 0/1 bytes as numpy bool.
template <class T>
py::array make_view(const T* data, const Shape& shape, const py::object& owner, bool as_bool = false) {
  py::dtype dtype = as_bool ? py::dtype("?") : py::dtype::of<T>();
  py::array a(dtype, shape, Shape{}, data, owner);
  a.attr("flags").attr("writeable") = false;
  return a;
}

// Copies of every array of a dict (copy=True results).
py::dict copy_dict(const py::dict& views) {
  py::dict out;
  for (auto item : views) out[item.first] = py::reinterpret_borrow<py::array>(item.second).attr("copy")();
  return out;
}

// Refuses a second concurrent call on one object (the GIL is released while it works).
class BusyGuard {
 public:
  BusyGuard(std::atomic<bool>& flag, const char* what) : flag_(flag) {
    if (flag_.exchange(true)) {
      throw std::runtime_error(std::string(what) +
                               ": called while another thread is inside a call on the same object");
    }
  }
  ~BusyGuard() { flag_ = false; }
  BusyGuard(const BusyGuard&) = delete;
  BusyGuard& operator=(const BusyGuard&) = delete;

 private:
  std::atomic<bool>& flag_;
};

// Sets a Python exception of `type` whose text is `message` as UTF-8, with any byte that is not (a damaged
// file's, echoed in the message) shown as U+FFFD rather than losing the whole message.
void set_error(PyObject* type, const std::string& message) {
  PyObject* text = PyUnicode_DecodeUTF8(message.data(), py::ssize_t(message.size()), "replace");
  if (text == nullptr) {  // out of memory: whatever Python raised stands
    return;
  }
  PyErr_SetObject(type, text);
  Py_DECREF(text);
}

[[noreturn]] void raise(PyObject* type, const std::string& message) {
  set_error(type, message);
  throw py::error_already_set();
}

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}
std::string shape_text(const Shape& shape) {
  std::string s = "(";
  for (size_t i = 0; i < shape.size(); ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
  return s + (shape.size() == 1 ? ",)" : ")");
}

// `value` as an array (numpy converts lists); TypeError naming `what` otherwise.
py::array as_array(const py::handle& value, const std::string& what) {
  py::array a = py::array::ensure(value);
  if (!a)
    raise(PyExc_TypeError, what + ": expected a numpy array, got " + std::string(py::str(value.get_type())));
  return a;
}

void check_shape(const py::array& a, const Shape& want, const std::string& what) {
  bool ok = a.ndim() == py::ssize_t(want.size());
  for (size_t i = 0; ok && i < want.size(); ++i) ok = a.shape(i) == want[i];
  if (!ok) raise(PyExc_ValueError, what + ": shape " + shape_text(a) + ", expected " + shape_text(want));
}

// `a` as a C-contiguous array of T (converted where Flags include forcecast). A conversion numpy cannot make
// (no memory for the copy) is a MemoryError naming `what`, never a null array.
template <class T, int Flags = py::array::c_style>
py::array_t<T, Flags> contiguous(const py::array& a, const std::string& what) {
  auto c = py::array_t<T, Flags>::ensure(a);
  if (!c) raise(PyExc_MemoryError, what + ": no memory for a contiguous copy of shape " + shape_text(a));
  return c;
}

// A C-contiguous array of exactly T (no conversion: a wrong dtype is a TypeError naming `what`).
template <class T>
py::array_t<T, py::array::c_style> exact(const py::array& a, const std::string& what,
                                         const char* dtype_name) {
  if (!a.dtype().is(py::dtype::of<T>())) {
    raise(PyExc_TypeError, what + ": dtype " + std::string(py::str(a.dtype())) + ", expected " + dtype_name);
  }
  return contiguous<T>(a, what);
}

// A file path from a str or an os.PathLike (TypeError otherwise; ValueError for an embedded NUL byte).
std::string path_from(const py::object& value, const char* what) {
  const py::object p = py::module_::import("os").attr("fspath")(value);
  if (!py::isinstance<py::str>(p))
    raise(PyExc_TypeError, std::string(what) + ": expected a str or os.PathLike");
  std::string path = p.cast<std::string>();
  if (path.find('\0') != std::string::npos)
    raise(PyExc_ValueError, std::string(what) + ": the path holds a NUL byte");
  return path;
}

// A seed from any integer (Python or numpy; not bool) in [0, 2^64 - 1].
uint64_t seed_from(const py::object& value) {
  if (PyBool_Check(value.ptr()) || PyIndex_Check(value.ptr()) == 0) {
    raise(PyExc_TypeError, "seed: expected an integer, got " + std::string(py::str(value.get_type())));
  }
  const auto seed = py::reinterpret_steal<py::int_>(PyNumber_Index(value.ptr()));
  if (!seed) throw py::error_already_set();
  const py::int_ lo(0), hi(std::numeric_limits<uint64_t>::max());
  if (seed < lo || seed > hi) {
    raise(PyExc_ValueError,
          "seed = " + std::string(py::str(py::handle(seed))) + " is invalid: must be in [0, 2^64 - 1]");
  }
  return seed.cast<uint64_t>();
}

// ---------------------------------------------------------------------------------------------------------
// BatchEnv

class BatchEnv {
  // What the arrays handed to Python keep alive: the batch, and the all-zero `terminated` flags.
  struct Keeper {
    std::shared_ptr<batch::BatchSim> sim;
    std::vector<uint8_t> zeros;
  };

 public:
  BatchEnv(const std::string& scene, const phys::WorldConfig& world, int num_envs, int threads, uint64_t seed)
      : scene_(scene) {
    if (num_envs < 1 || num_envs > (1 << 22)) {
      raise(PyExc_ValueError,
            "num_envs = " + std::to_string(num_envs) + " is invalid: must be in [1, 4194304]");
    }
    if (threads < 0) {
      raise(PyExc_ValueError,
            "threads = " + std::to_string(threads) + " is invalid: must be >= 0 (0 = every hardware thread)");
    }
    batch::BatchConfig config;
    config.world = world;
    config.num_envs = num_envs;
    config.threads = batch::usable_threads(threads);
    config.seed = seed;
    config.validate();  // physics::ConfigError (ValueError) naming the field
    batch::check_memory("num_envs = " + std::to_string(num_envs), config.estimated_bytes());
    sim_ = std::make_shared<batch::BatchSim>(config);
    const batch::Layout& L = sim_->layout();
    layout_ = L;
    config_ = sim_->config();
    actions_.resize(size_t(num_envs) * L.max_agents);

    // Every field viewed once: the buffers never move while the sim lives, and the arrays keep it alive
    // through a capsule (not through this object, so no reference cycle).
    auto* keep = new Keeper{sim_, std::vector<uint8_t>(size_t(num_envs), 0)};
    owner_ = py::capsule(keep, [](void* p) { delete static_cast<Keeper*>(p); });
    const batch::BatchState& s = sim_->state();
    const py::ssize_t E = num_envs;
    using batch::Layout;  // the field sizes below name it
#define HNS_VIEW_FIELD(type, name, count, doc)                                    \
  {                                                                               \
    Shape shape{E};                                                               \
    for (py::ssize_t d : field_dims(#name, size_t(count), L)) shape.push_back(d); \
    fields_[#name] = make_view(s.name.data(), shape, owner_);                     \
    docs_[#name] = doc;                                                           \
  }
    HNS_BATCH_FIELDS(HNS_VIEW_FIELD)
#undef HNS_VIEW_FIELD
    for (const char* name : kObsFields) obs_[name] = fields_[name];
    if (L.max_sites > 0)
      for (const char* name : kSiteObsFields) obs_[name] = fields_[name];
    truncated_ = make_view(s.done.data(), Shape{E}, owner_, /*as_bool=*/true);
    // The final observation of every env whose episode ended in a step (Gymnasium's final_obs): the batch
    // keeps a copy of each observation field, viewed like the field.
    std::vector<std::string> obs_names;
    for (auto item : obs_) obs_names.push_back(py::str(item.first));
    sim_->keep_final(obs_names);
    for (const std::string& name : obs_names) {
      py::array field = py::reinterpret_borrow<py::array>(obs_[name.c_str()]);
      Shape shape(field.shape(), field.shape() + field.ndim());
      py::array view(field.dtype(), shape, Shape{}, sim_->final_field(name), owner_);
      view.attr("flags").attr("writeable") = false;
      final_obs_[name.c_str()] = view;
    }
    final_mask_view_ = make_view(sim_->final_mask().data(), Shape{E}, owner_, /*as_bool=*/true);
    terminated_view_ = make_view(keep->zeros.data(), Shape{E}, owner_, /*as_bool=*/true);
  }

  py::tuple reset(std::optional<py::handle> episodes, bool copy, const py::object& seed,
                  const py::object& options) {
    BusyGuard busy(busy_, "BatchEnv.reset");
    check_open("reset");
    if (!options.is_none()) {
      if (!py::isinstance<py::dict>(options)) raise(PyExc_TypeError, "options: expected a dict or None");
      for (auto item : py::reinterpret_borrow<py::dict>(options)) {
        const std::string key = py::str(item.first);
        if (key != "episodes")
          raise(PyExc_ValueError, "options: unknown key '" + key + "' (known: episodes)");
        if (episodes && !episodes->is_none())
          raise(PyExc_ValueError, "episodes given twice: as an argument and in options");
        episodes = item.second;
      }
    }
    const bool seeded = !seed.is_none();
    if (seeded) {
      const uint64_t s = seed_from(seed);
      config_.seed = s;
      py::gil_scoped_release release;
      sim_->reseed(s);
    }
    const bool first = !reset_called_;
    reset_called_ = true;
    if (!seeded && !first && (!episodes || episodes->is_none())) {
      // A later reset without a seed: every env starts its next episode (never one it has played).
      const batch::BatchState& s = sim_->state();
      std::vector<int32_t> next(static_cast<size_t>(num_envs()));
      for (int e = 0; e < num_envs(); ++e) {
        if (s.episode[size_t(e)] >= (1 << 30) - 1)
          raise(PyExc_ValueError, "env " + std::to_string(e) +
                                      " has played 2^30 episodes: reset(seed=...) "
                                      "starts over");
        next[size_t(e)] = s.episode[size_t(e)] + 1;
      }
      {
        py::gil_scoped_release release;
        sim_->reset(next);
      }
      return py::make_tuple(observations(copy), info(copy));
    }
    if (episodes && !episodes->is_none()) {
      py::array a = as_array(*episodes, "episodes");
      if (a.dtype().kind() != 'i' && a.dtype().kind() != 'u') {
        raise(PyExc_TypeError,
              "episodes: dtype " + std::string(py::str(a.dtype())) + " is not an integer dtype");
      }
      check_shape(a, Shape{py::ssize_t(num_envs())}, "episodes");
      // At most 2^30 - 1: the env's int32 episode counter keeps 2^30 episodes of headroom.
      std::vector<int32_t> eps(static_cast<size_t>(num_envs()));
      auto check_copy = [&](const auto* v) {
        for (int e = 0; e < num_envs(); ++e) {
          if (static_cast<uint64_t>(v[e]) > uint64_t((1 << 30) - 1)) {  // negative values wrap
            raise(PyExc_ValueError, "episodes[" + std::to_string(e) + "] = " + std::to_string(+v[e]) +
                                        " is invalid: must be in [0, 2^30 - 1]");
          }
          eps[size_t(e)] = int32_t(v[e]);
        }
      };
      if (a.dtype().kind() == 'u') {
        check_copy(contiguous<uint64_t, py::array::c_style | py::array::forcecast>(a, "episodes").data());
      } else {
        check_copy(contiguous<int64_t, py::array::c_style | py::array::forcecast>(a, "episodes").data());
      }
      py::gil_scoped_release release;
      sim_->reset(eps);
    } else {
      py::gil_scoped_release release;
      sim_->reset();
    }
    return py::make_tuple(observations(copy), info(copy));
  }

  py::tuple step(const py::handle& actions, bool copy) {
    BusyGuard busy(busy_, "BatchEnv.step");
    check_open("step");
    read_actions(actions);
    {
      py::gil_scoped_release release;
      sim_->step(actions_);
    }
    py::object reward = fields_["reward"], truncated = truncated_, terminated = terminated_view_;
    if (copy) {
      reward = reward.attr("copy")();
      truncated = truncated.attr("copy")();
      terminated = terminated.attr("copy")();
    }
    return py::make_tuple(observations(copy), reward, terminated, truncated, info(copy));
  }

  py::dict observations(bool copy) const {
    check_open("observations");
    return copy ? copy_dict(obs_) : py::dict(obs_.attr("copy")());
  }
  py::dict state(bool copy) const {
    check_open("state");
    return copy ? copy_dict(fields_) : py::dict(fields_.attr("copy")());
  }
  py::dict field_docs() const {
    return py::dict(docs_.attr("copy")());
  }

  // Per-env bookkeeping and the episodes that ended in the last step.
  py::dict info(bool copy) const {
    py::dict d;
    for (const char* name : {"episode_return", "agent_exists", "agent_hider"}) {
      d[name] = copy ? py::object(fields_[name].attr("copy")()) : py::object(fields_[name]);
    }
    const auto finished = sim_->finished();
    const py::ssize_t n = py::ssize_t(finished.size());
    py::array_t<int32_t> env(n), episode(n), length(n);
    py::array_t<bool> discarded(n);
    const char* float_names[] = {"hider_return", "seeker_return",
#define HNS_EPISODE_STAT_NAME(name, doc) #name,
                                 HNS_EPISODE_STATS(HNS_EPISODE_STAT_NAME)
#undef HNS_EPISODE_STAT_NAME
    };
    std::vector<py::array_t<float>> floats;
    for (size_t k = 0; k < std::size(float_names); ++k) floats.emplace_back(n);
    for (py::ssize_t i = 0; i < n; ++i) {
      const batch::EpisodeStats& st = finished[size_t(i)];
      env.mutable_at(i) = st.env;
      episode.mutable_at(i) = st.episode;
      length.mutable_at(i) = st.length;
      discarded.mutable_at(i) = st.discarded;
      const float values[] = {st.hider_return, st.seeker_return,
#define HNS_EPISODE_STAT_VALUE(name, doc) st.name,
                              HNS_EPISODE_STATS(HNS_EPISODE_STAT_VALUE)
#undef HNS_EPISODE_STAT_VALUE
      };
      static_assert(std::size(values) == std::size(float_names));
      for (size_t k = 0; k < std::size(float_names); ++k) floats[k].mutable_at(i) = values[k];
    }
    // The same per env, as Gymnasium's vector envs give episode statistics: info["episode"][key] is (E,),
    // meaningful where info["_episode"] is true (the env's episode ended in this step), 0 elsewhere.
    const py::ssize_t num = num_envs();
    py::array_t<bool> has(num), per_discarded(num);
    py::array_t<int32_t> per_length(num), per_number(num);
    std::vector<py::array_t<float>> per_env;
    for (size_t k = 0; k < std::size(float_names); ++k) per_env.emplace_back(num);
    std::fill_n(has.mutable_data(), num, false);
    std::fill_n(per_discarded.mutable_data(), num, false);
    std::fill_n(per_length.mutable_data(), num, 0);
    std::fill_n(per_number.mutable_data(), num, 0);
    for (auto& a : per_env) std::fill_n(a.mutable_data(), num, 0.0f);
    for (py::ssize_t i = 0; i < n; ++i) {
      const py::ssize_t e = env.at(i);
      has.mutable_at(e) = true;
      per_length.mutable_at(e) = length.at(i);
      per_number.mutable_at(e) = episode.at(i);
      per_discarded.mutable_at(e) = discarded.at(i);
      for (size_t k = 0; k < std::size(float_names); ++k) per_env[k].mutable_at(e) = floats[k].at(i);
    }
    py::dict episode_info;
    episode_info["l"] = per_length;
    episode_info["episode"] = per_number;
    episode_info["discarded"] = per_discarded;
    for (size_t k = 0; k < std::size(float_names); ++k) episode_info[float_names[k]] = per_env[k];
    d["episode"] = episode_info;
    d["_episode"] = has;
    py::dict ended;
    ended["env"] = env;
    ended["episode"] = episode;
    ended["length"] = length;
    ended["discarded"] = discarded;
    for (size_t k = 0; k < std::size(float_names); ++k) ended[float_names[k]] = floats[k];
    d["finished"] = ended;
    d["unstable_resets"] = sim_->unstable_resets();
    d["final_obs"] = copy ? copy_dict(final_obs_) : py::dict(final_obs_.attr("copy")());
    d["_final_obs"] = copy ? py::object(final_mask_view_.attr("copy")()) : py::object(final_mask_view_);
    return d;
  }

  // The scene env `env` is playing (copies): walls, doors, counts and spawns.
  py::dict scene(int env) {
    BusyGuard busy(busy_, "BatchEnv.scene");  // a step may be replacing the scene meanwhile
    check_open("scene");
    if (env < 0 || env >= num_envs()) {
      raise(PyExc_IndexError, "env = " + std::to_string(env) + " is out of range: the batch has " +
                                  std::to_string(num_envs()) + " envs");
    }
    const phys::Scene& sc = sim_->world(env).scene();
    py::dict d;
    d["layout"] = phys::layout_name(sc.layout);
    d["outer_walls"] = sc.outer_walls;
    py::array_t<double> walls(Shape{py::ssize_t(sc.wall_boxes.size()), 6});
    for (size_t i = 0; i < sc.wall_boxes.size(); ++i) {
      const phys::StaticBox& w = sc.wall_boxes[i];
      const double v[6] = {w.cx, w.cy, w.cz, w.hx, w.hy, w.hz};
      for (int k = 0; k < 6; ++k) walls.mutable_at(py::ssize_t(i), k) = v[k];
    }
    d["walls"] = walls;
    py::array_t<double> cylinders(Shape{sc.has_target ? 1 : 0, 4});
    if (sc.has_target) {
      const double v[4] = {sc.target.x, sc.target.y, 0.5 * sc.target.sx, sc.target.sz};
      for (int k = 0; k < 4; ++k) cylinders.mutable_at(0, k) = v[k];
    }
    d["cylinders"] = cylinders;
    py::array_t<int32_t> doors(Shape{py::ssize_t(sc.doors.size()), 4});
    for (size_t i = 0; i < sc.doors.size(); ++i) {
      const phys::DoorCells& c = sc.doors[i];
      const int v[4] = {c.x1, c.y1, c.x2, c.y2};
      for (int k = 0; k < 4; ++k) doors.mutable_at(py::ssize_t(i), k) = v[k];
    }
    d["doors"] = doors;
    auto spawns = [](const std::vector<phys::Spawn>& list) {
      py::array_t<double> a(Shape{py::ssize_t(list.size()), 6});
      for (size_t i = 0; i < list.size(); ++i) {
        const phys::Spawn& sp = list[i];
        const double v[6] = {sp.x, sp.y, sp.z, sp.sx, sp.sy, sp.sz};
        for (int k = 0; k < 6; ++k) a.mutable_at(py::ssize_t(i), k) = v[k];
      }
      return a;
    };
    d["num_hiders"] = sc.num_hiders;
    d["num_seekers"] = sc.num_seekers;
    d["num_elongated"] = sc.num_elongated;
    d["agents"] = spawns(sc.agents);
    d["boxes"] = spawns(sc.boxes);
    d["ramps"] = spawns(sc.ramps);
    d["sites"] = spawns(sc.sites);  // blueprint's construction sites: centre, then 0.5 x 0.5 x 0
    return d;
  }

  int num_envs() const {
    return config_.num_envs;
  }
  const batch::Layout& layout() const {
    return layout_;
  }
  const batch::BatchConfig& config() const {
    return config_;
  }
  // Releases the simulator: its worlds and buffers are freed once no array the env handed out is alive
  // (those keep the memory they view). Everything but the properties then raises. Idempotent.
  void close() {
    BusyGuard busy(busy_, "BatchEnv.close");
    if (closed_) return;
    closed_ = true;
    fields_ = py::dict();
    obs_ = py::dict();
    truncated_ = py::array();
    terminated_view_ = py::array();
    final_obs_ = py::dict();
    final_mask_view_ = py::array();
    owner_ = py::capsule();
    sim_.reset();
  }
  bool closed() const {
    return closed_;
  }
  const std::string& scene_name() const {
    return scene_;
  }
  // Env `env` as it is now, drawn top-down (replay/render.hpp): uint8 (size, size, 3).
  py::array_t<uint8_t> render_rgb(int env, int size) {
    BusyGuard busy(busy_, "BatchEnv.render");  // a step may be moving the bodies meanwhile
    check_open("render");
    if (env < 0 || env >= num_envs()) {
      raise(PyExc_IndexError, "env = " + std::to_string(env) + " is out of range: the batch has " +
                                  std::to_string(num_envs()) + " envs");
    }
    if (size < 64 || size > 4096) {
      raise(PyExc_ValueError, "size = " + std::to_string(size) + " is invalid: must be in [64, 4096] pixels");
    }
    const replay::RgbImage im = replay::render_frame(replay::snapshot(*sim_, env, scene_), 0, size);
    py::array_t<uint8_t> out({im.height, im.width, 3});
    std::memcpy(out.mutable_data(), im.rgb.data(), im.rgb.size());
    return out;
  }
  uintptr_t field_address(const std::string& name) const {
    check_open("_field_address");
    if (!fields_.contains(name)) raise(PyExc_KeyError, "no batch field " + name);
    return uintptr_t(py::reinterpret_borrow<py::array>(fields_[name.c_str()]).data());
  }

 private:
  void check_open(const char* what) const {
    if (closed_) raise(PyExc_RuntimeError, std::string("BatchEnv.") + what + ": the env is closed");
  }
  // Checks an (num_envs, max_agents, 5) integer array and copies it into actions_.
  void read_actions(const py::handle& value) {
    py::array a = as_array(value, "actions");
    if (a.dtype().kind() != 'i' && a.dtype().kind() != 'u') {
      raise(PyExc_TypeError, "actions: dtype " + std::string(py::str(a.dtype())) +
                                 " is not an integer dtype (use int or uint8: movement bins 0..10, grab and "
                                 "lock 0/1)");
    }
    const int A = layout().max_agents;
    check_shape(a, Shape{num_envs(), A, 5}, "actions");
    auto check_copy = [&](const auto* p) {
      for (size_t i = 0; i < actions_.size(); ++i) {
        const auto* x = p + i * 5;
        for (int k = 0; k < 5; ++k) {
          const int hi = k < 3 ? phys::kMoveBins - 1 : 1;
          if (static_cast<uint64_t>(x[k]) > uint64_t(hi)) {  // a negative value wraps to a huge one
            raise(PyExc_ValueError, "actions[" + std::to_string(i / A) + ", " + std::to_string(i % A) + ", " +
                                        std::to_string(k) + "] = " + std::to_string(+x[k]) +
                                        " is out of range: " +
                                        (k < 3 ? "movement bins are 0..10" : "grab and lock are 0 or 1"));
          }
        }
        actions_[i] = {uint8_t(x[0]), uint8_t(x[1]), uint8_t(x[2]), uint8_t(x[3]), uint8_t(x[4])};
      }
    };
    if (a.dtype().is(py::dtype::of<uint8_t>())) {
      check_copy(contiguous<uint8_t>(a, "actions").data());
    } else if (a.dtype().kind() == 'u') {
      check_copy(contiguous<uint64_t, py::array::c_style | py::array::forcecast>(a, "actions").data());
    } else {
      check_copy(contiguous<int64_t, py::array::c_style | py::array::forcecast>(a, "actions").data());
    }
  }

  std::string scene_;
  std::shared_ptr<batch::BatchSim> sim_;
  std::vector<phys::AgentAction> actions_;
  py::capsule owner_;
  py::dict fields_, docs_, obs_;
  py::array truncated_;        // bool view of the batch's done flags: the horizon ends a game (a time limit)
  py::array terminated_view_;  // always false (Keeper::zeros): no game ends otherwise
  py::dict final_obs_;         // views of the batch's kept final observations (keep_final)
  py::array final_mask_view_;  // bool: the env's episode ended in the last step
  bool reset_called_ = false;  // a reset() without seed or episodes after the first starts new episodes
  bool closed_ = false;
  batch::Layout layout_;       // the batch's, kept for the properties after close()
  batch::BatchConfig config_;  // likewise (its seed follows reset(seed=...))
  std::atomic<bool> busy_{false};
};

std::unique_ptr<BatchEnv> make_env(const std::string& scene, int num_envs, int threads,
                                   const py::object& seed, std::optional<int> hiders,
                                   std::optional<int> seekers, std::optional<int> boxes,
                                   std::optional<int> ramps, std::optional<int> horizon) {
  phys::WorldConfig world = phys::world_preset(scene);
  phys::apply_overrides(world, phys::CountOverrides{hiders, seekers, boxes, ramps});
  if (horizon) {
    if (*horizon < 1) {
      raise(PyExc_ValueError, "horizon = " + std::to_string(*horizon) + " is invalid: must be >= 1");
    }
    world.horizon = *horizon;
  }
  return std::make_unique<BatchEnv>(scene, world, num_envs, threads, seed_from(seed));
}

// ---------------------------------------------------------------------------------------------------------
// Policy

class Policy {
 public:
  Policy(const std::string& path, uint64_t seed) : path_(path) {
    if (!std::filesystem::exists(path)) raise(PyExc_FileNotFoundError, path + ": no such file");
    try {
      policy_ = ppo::Policy::from_checkpoint(path, seed);
    } catch (const phys::ConfigError& e) {
      raise(PyExc_ValueError, path + ": " + e.what());
    } catch (const std::runtime_error& e) {
      raise(PyExc_ValueError, e.what());
    }
  }

  py::tuple act(const py::dict& obs, const py::handle& state_in) {
    BusyGuard busy(busy_, "Policy.act");
    const nn::ObsShape& S = policy_->obs_shape();
    const py::ssize_t A = S.max_agents, O = S.num_other_agents(), B = S.max_boxes, R = S.max_ramps,
                      C = S.max_sites;
    auto get = [&](const char* key) {
      if (!obs.contains(key)) raise(PyExc_KeyError, std::string("obs['") + key + "'] is missing");
      return as_array(obs[key], std::string("obs['") + key + "']");
    };
    py::array self = get("obs_self");
    if (self.ndim() < 1) raise(PyExc_ValueError, "obs['obs_self']: expected (num_envs, max_agents, 11)");
    const py::ssize_t E = self.shape(0);
    if (E < 1 || E > (1 << 22)) {
      raise(PyExc_ValueError,
            "obs['obs_self']: " + std::to_string(E) + " envs; a policy acts for 1 to 4194304");
    }
    std::vector<py::object> keep;  // the contiguous arrays read below
    auto floats = [&](const char* key, Shape per_row) {
      py::array a = get(key);
      Shape want{E, A};
      want.insert(want.end(), per_row.begin(), per_row.end());
      check_shape(a, want, std::string("obs['") + key + "']");
      auto c = exact<float>(a, std::string("obs['") + key + "']", "float32");
      keep.push_back(c);
      return c.data();
    };
    auto bytes = [&](const char* key, py::ssize_t n) {
      py::array a = get(key);
      check_shape(a, Shape{E, A, n}, std::string("obs['") + key + "']");
      if (a.dtype().is(py::dtype("?"))) a = a.attr("view")(py::dtype::of<uint8_t>());
      auto c = exact<uint8_t>(a, std::string("obs['") + key + "']", "uint8 or bool");
      keep.push_back(c);
      return c.data();
    };
    auto counters = [&](const char* key) {
      py::array a = get(key);
      check_shape(a, Shape{E}, std::string("obs['") + key + "']");
      auto c = exact<int32_t>(a, std::string("obs['") + key + "']", "int32");
      keep.push_back(c);
      return c.data();
    };
    ppo::StepObsView v;
    v.obs_self = floats("obs_self", {S.self_features});
    v.lidar = floats("lidar", {S.lidar_rays});
    v.obs_agents = floats("obs_agents", {O, S.agent_features});
    v.obs_boxes = floats("obs_boxes", {B, S.box_features});
    v.obs_ramps = floats("obs_ramps", {R, S.ramp_features});
    v.mask_agents = bytes("mask_agents", O);
    v.mask_boxes = bytes("mask_boxes", B);
    v.mask_ramps = bytes("mask_ramps", R);
    v.value_mask_agents = bytes("value_mask_agents", O);
    v.value_mask_boxes = bytes("value_mask_boxes", B);
    v.value_mask_ramps = bytes("value_mask_ramps", R);
    if (C > 0) {  // scenes with construction sites only
      v.obs_sites = floats("obs_sites", {C, S.site_features});
      v.mask_sites = bytes("mask_sites", C);
      v.value_mask_sites = bytes("value_mask_sites", C);
    }
    v.step_count = counters("step_count");
    v.episode = counters("episode");

    const py::ssize_t sw = policy_->state_width();
    py::array state = as_array(state_in, "state");
    check_shape(state, Shape{2, E, A, sw}, "state");
    auto state_c = exact<float>(state, "state", "float32");
    py::array_t<float> next(Shape{2, E, A, sw});
    std::memcpy(next.mutable_data(), state_c.data(), sizeof(float) * size_t(2 * E * A * sw));
    py::array_t<uint8_t> actions(Shape{E, A, 5});
    {
      py::gil_scoped_release release;
      float* p = next.mutable_data();
      std::vector<phys::AgentAction> out(size_t(E * A));
      policy_->act(v, int(E), p, p + E * A * sw, out);
      std::memcpy(actions.mutable_data(), out.data(), out.size() * sizeof(phys::AgentAction));
    }
    return py::make_tuple(actions, next);
  }

  py::array_t<float> initial_state(int num_envs) const {
    if (num_envs < 1) {
      raise(PyExc_ValueError, "num_envs = " + std::to_string(num_envs) + " is invalid: must be >= 1");
    }
    py::array_t<float> s(Shape{2, num_envs, policy_->obs_shape().max_agents, policy_->state_width()});
    std::memset(s.mutable_data(), 0, sizeof(float) * size_t(s.size()));
    return s;
  }

  std::unique_ptr<BatchEnv> make_env(int num_envs, int threads, const py::object& seed) const {
    return std::make_unique<BatchEnv>(policy_->config().scene, policy_->config().world(), num_envs, threads,
                                      seed_from(seed));
  }

  const ppo::TrainConfig& config() const { return policy_->config(); }
  int state_width() const { return policy_->state_width(); }
  int max_agents() const { return policy_->obs_shape().max_agents; }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::unique_ptr<ppo::Policy> policy_;
  std::atomic<bool> busy_{false};
};

// ---------------------------------------------------------------------------------------------------------
// Trajectory files and metrics

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
      replay::play_config(scene, policy.get(), phys::CountOverrides{hiders, seekers, boxes, ramps}, episodes,
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
}  // namespace hns::python

PYBIND11_MODULE(_hns, m) {
  using namespace hns::python;
  m.doc() = "hns: the batch hide-and-seek simulator, trained policies and recordings (docs/python.md)";
  m.attr("__version__") = HNS_VERSION;
  m.attr("isa") = HNS_ISA_SETTING;
  py::tuple scenes(hns::physics::kScenes.size());
  py::dict scene_info;
  for (size_t i = 0; i < scenes.size(); ++i) {
    const hns::physics::SceneInfo& s = hns::physics::kScenes[i];
    scenes[i] = s.name;
    py::dict row;
    row["family"] = hns::physics::family_name(s.family);
    row["summary"] = s.summary;
    scene_info[s.name] = row;
  }
  m.attr("scenes") = scenes;
  m.attr("scene_info") = scene_info;
  // TrajectoryError (a ValueError) with the message kept even where it quotes a damaged file's bytes.
  static py::exception<hns::replay::TrajectoryError> trajectory_error(m, "TrajectoryError", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const hns::replay::TrajectoryError& e) {
      set_error(trajectory_error.ptr(), e.what());
    }
  });

  py::class_<BatchEnv>(m, "BatchEnv", py::dynamic_attr(), R"doc(
A batch of hide-and-seek games stepped together (TBB threads; the GIL is released while stepping).

BatchEnv(scene="quadrant", num_envs=64, threads=0, seed=1, hiders=None, seekers=None, boxes=None,
         ramps=None, horizon=None)

Arrays returned by reset(), step() and state() view the batch's own buffers (no copy, read-only): they
stay valid as long as any of them or the env lives, and their contents change at the next step() or
reset(). Pass copy=True for arrays of your own.)doc")
      .def(py::init(&make_env), py::arg("scene") = "quadrant", py::arg("num_envs") = 64,
           py::arg("threads") = 0, py::arg("seed") = py::int_(1), py::arg("hiders") = py::none(),
           py::arg("seekers") = py::none(), py::arg("boxes") = py::none(), py::arg("ramps") = py::none(),
           py::arg("horizon") = py::none())
      .def("reset", &BatchEnv::reset, py::arg("episodes") = py::none(), py::arg("copy") = false,
           py::kw_only(), py::arg("seed") = py::none(), py::arg("options") = py::none(),
           "Starts new episodes and returns (obs, info): with seed, episode 0 of every env drawn from that "
           "seed; the first reset without one, episode 0; later resets without one, every env's next "
           "episode; episodes (or options={'episodes': ...}): episodes[e] of env e.")
      .def(
          "step", &BatchEnv::step, py::arg("actions"), py::arg("copy") = false,
          "One step of every env. actions: integer array (num_envs, max_agents, 5): movement x, y, turn bins "
          "0..10 (5 = none), grab and lock 0/1; padding slots are ignored. Returns (obs, reward, terminated, "
          "truncated, info); an env whose episode ended is reset in the same step (its obs is the new "
          "episode's first).")
      .def("observations", &BatchEnv::observations, py::arg("copy") = false,
           "The current observation dict (what reset() and step() return).")
      .def(
          "state", &BatchEnv::state, py::arg("copy") = false,
          "Every field of the batch state (bodies, shapes, perception, rewards, statistics, observations) by "
          "name, shaped (num_envs, ...).")
      .def("field_docs", &BatchEnv::field_docs, "What each state() field holds, with units and shape.")
      .def("scene", &BatchEnv::scene, py::arg("env"),
           "The scene env `env` plays now: walls (n, 6: centre, half extents, m), doors (cells), spawns.")
      .def("_render_rgb", &BatchEnv::render_rgb, py::arg("env"), py::arg("size"))
      .def("_field_address", &BatchEnv::field_address)
      .def("close", &BatchEnv::close,
           "Releases the simulator (its memory goes once no array the env handed out is alive); reset, step "
           "and "
           "the other methods then raise RuntimeError. Also called on leaving a `with` block.")
      .def("__enter__", [](py::object self) { return self; })
      .def(
          "__exit__",
          [](BatchEnv& e, const py::args&) {
            e.close();
            return false;
          },
          "Calls close().")
      .def_property_readonly("closed", &BatchEnv::closed)
      .def_property_readonly("num_envs", &BatchEnv::num_envs)
      .def_property_readonly("max_agents", [](const BatchEnv& e) { return e.layout().max_agents; })
      .def_property_readonly("max_boxes", [](const BatchEnv& e) { return e.layout().max_boxes; })
      .def_property_readonly("max_ramps", [](const BatchEnv& e) { return e.layout().max_ramps; })
      .def_property_readonly("max_sites", [](const BatchEnv& e) { return e.layout().max_sites; })
      .def_property_readonly("horizon", [](const BatchEnv& e) { return e.config().world.horizon; })
      .def_property_readonly("prep_steps", [](const BatchEnv& e) { return e.config().world.prep_steps(); })
      .def_property_readonly("threads", [](const BatchEnv& e) { return e.config().threads; })
      .def_property_readonly("seed", [](const BatchEnv& e) { return e.config().seed; })
      .def_property_readonly("scene_name", &BatchEnv::scene_name);

  py::class_<Policy>(m, "Policy", R"doc(
The policy of a training checkpoint, sampling actions like `hns play --checkpoint`.

Policy.load(path, seed=1); act(obs, state) -> (actions, new_state) where obs is a BatchEnv observation dict
and state a float32 array (2, num_envs, max_agents, state_width): the policy's and the value net's LSTM
states (initial_state(num_envs) gives zeros; an env at step_count 0 has its states zeroed first).)doc")
      .def_static(
          "load",
          [](const py::object& path, const py::object& seed) {
            return std::make_unique<Policy>(path_from(path, "path"), seed_from(seed));
          },
          py::arg("path"), py::arg("seed") = py::int_(1))
      .def("act", &Policy::act, py::arg("obs"), py::arg("state"))
      .def("initial_state", &Policy::initial_state, py::arg("num_envs"))
      .def("make_env", &Policy::make_env, py::arg("num_envs") = 64, py::arg("threads") = 0,
           py::arg("seed") = py::int_(1), "A BatchEnv of the game the checkpoint was trained on.")
      .def_property_readonly("scene", [](const Policy& p) { return p.config().scene; })
      .def_property_readonly("model", [](const Policy& p) { return p.config().model; })
      .def_property_readonly("precision", [](const Policy& p) { return p.config().precision; })
      .def_property_readonly("config_json", [](const Policy& p) { return p.config().to_json(); })
      .def_property_readonly("state_width", &Policy::state_width)
      .def_property_readonly("max_agents", &Policy::max_agents)
      .def_property_readonly("path", &Policy::path);

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
