#include "batch_env.hpp"

namespace hns::python {

std::unique_ptr<BatchEnv> make_env(const std::string& scene, int num_envs, int threads,
                                   const py::object& seed, std::optional<int> hiders,
                                   std::optional<int> seekers, std::optional<int> boxes,
                                   std::optional<int> ramps, std::optional<int> horizon) {
  batch::BatchConfig game = batch::scene_config(scene);
  batch::apply_overrides(game.world, batch::CountOverrides{hiders, seekers, boxes, ramps});
  if (horizon) {
    if (*horizon < 1) {
      raise(PyExc_ValueError, "horizon = " + std::to_string(*horizon) + " is invalid: must be >= 1");
    }
    game.world.horizon = *horizon;
  }
  return std::make_unique<BatchEnv>(scene, game, num_envs, threads, seed_from(seed));
}

void bind_batch_env(py::module_& m) {
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
}

}  // namespace hns::python
