// hns.Policy: the policy of a training checkpoint acting on BatchEnv observation dicts.
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "batch_env.hpp"
#include "common.hpp"
#include "nn/obs_store.hpp"
#include "ppo/policy.hpp"

namespace hns::python {
namespace {

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
    const py::ssize_t A = S.max_agents;
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
    // Field f of nn's list, shaped (num_envs, max_agents) + its dimensions per agent row; features float32,
    // masks uint8 or bool.
    auto read = [&](const nn::ObsField& f) -> const void* {
      py::array a = get(f.name);
      Shape want{E, A};
      for (int d : nn::row_dims(S, f)) want.push_back(d);
      const std::string what = std::string("obs['") + f.name + "']";
      check_shape(a, want, what);
      if (!f.mask) {
        auto c = exact<float>(a, what, "float32");
        keep.push_back(c);
        return c.data();
      }
      if (a.dtype().is(py::dtype("?"))) a = a.attr("view")(py::dtype::of<uint8_t>());
      auto c = exact<uint8_t>(a, what, "uint8 or bool");
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
    // The fields in the dict's order (the fourth entity type's last, in scenes with one), then the counters.
    ppo::StepObsView v;
    for (const bool sites : {false, true}) {
      if (sites && S.max_sites == 0) break;
#define HNS_READ_OBS_FIELD(name, member, type, axis, key) \
  if ((nn::axis == nn::kObsSiteAxis) == sites)            \
    v.name = static_cast<const type*>(read(HNS_OBS_FIELD_INFO(name, member, type, nn::axis, nn::key)));
      HNS_OBS_FIELDS(HNS_READ_OBS_FIELD)
#undef HNS_READ_OBS_FIELD
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
    return std::make_unique<BatchEnv>(policy_->config().scene, policy_->config().batch_config(), num_envs,
                                      threads, seed_from(seed));
  }

  const ppo::TrainConfig& config() const {
    return policy_->config();
  }
  int state_width() const {
    return policy_->state_width();
  }
  int max_agents() const {
    return policy_->obs_shape().max_agents;
  }
  const std::string& path() const {
    return path_;
  }

 private:
  std::string path_;
  std::unique_ptr<ppo::Policy> policy_;
  std::atomic<bool> busy_{false};
};

}  // namespace

void bind_policy(py::module_& m) {
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
}

}  // namespace hns::python
