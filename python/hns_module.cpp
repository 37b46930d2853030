// The compiled part of the Python package `hns` (hns/_hns*.so; python/hns/__init__.py is its front):
// the batch simulator as a Gymnasium-style vector environment whose arrays view the batch's own buffers,
// trained policies, and the trajectory and metrics readers. Thin by design: argument checks and array
// plumbing here, the work in the libraries (hns_batch, hns_ppo, hns_replay). docs/python.md is the manual.
#include "batch/scenes.hpp"
#include "common.hpp"

PYBIND11_MODULE(_hns, m) {
  using namespace hns::python;
  m.doc() = "hns: the batch hide-and-seek simulator, trained policies and recordings (docs/python.md)";
  m.attr("__version__") = HNS_VERSION;
  m.attr("isa") = HNS_ISA_SETTING;
  py::tuple scenes(hns::batch::kScenes.size());
  py::dict scene_info;
  for (size_t i = 0; i < scenes.size(); ++i) {
    const hns::batch::SceneInfo& s = hns::batch::kScenes[i];
    scenes[i] = s.name;
    py::dict row;
    row["family"] = hns::batch::family_name(s.family);
    row["summary"] = s.summary;
    scene_info[s.name] = row;
  }
  m.attr("scenes") = scenes;
  m.attr("scene_info") = scene_info;
  bind_batch_env(m);
  bind_policy(m);
  bind_recordings(m);
}
