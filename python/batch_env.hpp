// The batch simulator as a Gymnasium-style vector environment (Python's hns.BatchEnv) whose arrays view the
// batch's own buffers: every BatchState field shaped by its own count (batch/field_dims.hpp), the
// observation dict's keys the observation fields of nn's list (nn/obs_store.hpp).
#pragma once

#include <algorithm>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "batch/batch_sim.hpp"
#include "batch/field_dims.hpp"
#include "batch/host.hpp"
#include "batch/scenes.hpp"
#include "common.hpp"
#include "nn/obs_store.hpp"
#include "physics/scene.hpp"
#include "replay/recorder.hpp"
#include "replay/render.hpp"

namespace hns::python {

// The keys of a step's observation dict: nn's observation fields (the policy's and the value net's inputs)
// but the fourth entity type's, the two per-env counters a policy needs (step_count 0 starts an episode:
// LSTM states zeroed; the episode number seeds its sampling stream), then, in scenes with the fourth entity
// type (blueprint's construction sites, the food variants' items), its fields.
inline std::vector<std::string> observation_keys(bool sites) {
  std::vector<std::string> keys;
  for (const nn::ObsField& f : nn::kObsFieldList)
    if (f.axis != nn::kObsSiteAxis) keys.push_back(f.name);
  keys.push_back("step_count");
  keys.push_back("episode");
  for (const nn::ObsField& f : nn::kObsFieldList)
    if (sites && f.axis == nn::kObsSiteAxis) keys.push_back(f.name);
  return keys;
}

class BatchEnv {
  // What the arrays handed to Python keep alive: the batch, and the all-zero `terminated` flags.
  struct Keeper {
    std::shared_ptr<batch::BatchSim> sim;
    std::vector<uint8_t> zeros;
  };

 public:
  // `game` with num_envs envs, `threads` threads and `seed` (the scene is its name, for the recordings).
  BatchEnv(const std::string& scene, const batch::BatchConfig& game, int num_envs, int threads, uint64_t seed)
      : scene_(scene) {
    if (num_envs < 1 || num_envs > (1 << 22)) {
      raise(PyExc_ValueError,
            "num_envs = " + std::to_string(num_envs) + " is invalid: must be in [1, 4194304]");
    }
    if (threads < 0) {
      raise(PyExc_ValueError,
            "threads = " + std::to_string(threads) + " is invalid: must be >= 0 (0 = every hardware thread)");
    }
    batch::BatchConfig config = game;
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
#define HNS_VIEW_FIELD(type, name, count, doc)                                     \
  {                                                                                \
    Shape shape{E};                                                                \
    for (int64_t d : batch::field_dims(#name, L)) shape.push_back(py::ssize_t(d)); \
    fields_[#name] = make_view(s.name.data(), shape, owner_);                      \
    docs_[#name] = doc;                                                            \
  }
    HNS_BATCH_FIELDS(HNS_VIEW_FIELD)
#undef HNS_VIEW_FIELD
    for (const std::string& name : observation_keys(L.max_sites > 0))
      obs_[name.c_str()] = fields_[name.c_str()];
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
    // Every argument is checked before anything changes: a refused call leaves the env as it was.
    std::optional<uint64_t> new_seed;
    if (!seed.is_none()) new_seed = seed_from(seed);
    std::optional<std::vector<int32_t>> eps;
    if (episodes && !episodes->is_none()) eps = episode_list(*episodes);
    const bool first = !reset_called_;
    if (!new_seed && !first && !eps) {
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
    reset_called_ = true;
    if (new_seed) config_.seed = *new_seed;  // read by the seed property, under the GIL
    {
      py::gil_scoped_release release;
      if (new_seed) sim_->reseed(*new_seed);
      if (eps) {
        sim_->reset(*eps);
      } else {
        sim_->reset();
      }
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
  // reset()'s episodes argument: one episode number per env, each in [0, 2^30 - 1] (the env's int32 episode
  // counter keeps 2^30 episodes of headroom).
  std::vector<int32_t> episode_list(py::handle episodes) {
    py::array a = as_array(episodes, "episodes");
    if (a.dtype().kind() != 'i' && a.dtype().kind() != 'u') {
      raise(PyExc_TypeError,
            "episodes: dtype " + std::string(py::str(a.dtype())) + " is not an integer dtype");
    }
    check_shape(a, Shape{py::ssize_t(num_envs())}, "episodes");
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
    return eps;
  }

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

// BatchEnv(scene, ...) as Python calls it: the scene's preset with the count and horizon overrides.
std::unique_ptr<BatchEnv> make_env(const std::string& scene, int num_envs, int threads,
                                   const py::object& seed, std::optional<int> hiders,
                                   std::optional<int> seekers, std::optional<int> boxes,
                                   std::optional<int> ramps, std::optional<int> horizon);

}  // namespace hns::python
