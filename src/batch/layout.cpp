// The sizes of a batch (Layout), its state's allocation and its memory estimate, and the checks of a batch
// config: everything fixed when a BatchSim is built, before any env steps.
#include <algorithm>
#include <sstream>

#include "batch/batch_sim.hpp"

namespace hns::batch {
namespace {

// Most wall pieces a scene of this config can have (each interior wall splits in two at its door).
int max_walls(const physics::SceneConfig& scene) {
  switch (scene.layout) {
    case physics::Layout::kQuadrant:
      return 4 + 2 * 2;
    case physics::Layout::kRandomWalls:
      return 4 + 2 * std::max(0, scene.rooms.max - 1);
    case physics::Layout::kVarTri:
    case physics::Layout::kCounting:
      return 4 + 2;
    default:
      return 4;
  }
}

}  // namespace

void BatchConfig::validate() const {
  world.validate();
  rules.validate(world);
  world.scene.check_placeable();
  auto check = [](bool ok, const char* field, long long value, const char* allowed) {
    if (!ok) {
      std::ostringstream out;
      out << field << " = " << value << " is invalid: " << allowed;
      throw physics::ConfigError(out.str());
    }
  };
  check(num_envs >= 1 && num_envs <= (1 << 22), "envs", num_envs, "must be in [1, 4194304]");
  check(threads >= 1 && threads <= 4096, "threads", threads, "must be in [1, 4096]");
  check(envs_per_task >= 1, "envs_per_task", envs_per_task, "must be >= 1");
  check(first_env >= 0, "first_env", first_env, "must be >= 0");
}

void BatchState::allocate(const Layout& L, int num_envs) {
#define HNS_ALLOCATE_FIELD(type, name, count, doc) name.resize(size_t(num_envs) * size_t(count));
  HNS_BATCH_FIELDS(HNS_ALLOCATE_FIELD)
#undef HNS_ALLOCATE_FIELD
}

Layout Layout::of(const BatchConfig& config) {
  const physics::SceneConfig& scene = config.world.scene;
  Layout L;
  L.max_agents = config.agent_slots();
  L.max_boxes = scene.boxes.max;
  L.max_ramps = std::max(scene.ramps.max, config.rules.obs_min_ramps);
  L.construction_sites = scene.sites.max;
  L.max_food = scene.food.max;  // SceneConfig::validate() allows sites or food, not both
  L.max_sites = std::max(L.construction_sites, L.max_food);
  L.site_features = L.max_food > 0             ? Layout::kFoodFeatures
                    : L.construction_sites > 0 ? Layout::kConstructionSiteFeatures
                                               : 0;
  L.max_walls = ::hns::batch::max_walls(scene);
  L.others = std::max(0, L.max_agents - 1);
  L.shape_boxes = L.max_walls + L.max_boxes;
  L.shape_wedges = L.max_ramps;
  L.shape_spheres = Layout::kSpheresPerAgent * L.max_agents;
  L.shape_cylinders = scene.target_diameter_max > 0 ? 1 : 0;
  return L;
}

size_t Layout::state_bytes_per_env() const {
  const Layout& L = *this;
  size_t bytes = 0;
#define HNS_FIELD_BYTES(type, name, count, doc) bytes += size_t(count) * sizeof(type);
  HNS_BATCH_FIELDS(HNS_FIELD_BYTES)
#undef HNS_FIELD_BYTES
  return bytes;
}

size_t BatchConfig::estimated_bytes() const {
  // One world: about 26 KB of ODE world, spaces, threading and scratch, 2.1 KB per body slot (ODE body,
  // geoms, auto-disable buffers, World bookkeeping) and 0.2 KB per wall: fitted to the resident memory of
  // 1000 and 4000 envs of both games (42 KB a quadrant world, 63 KB a full one).
  const Layout L = Layout::of(*this);
  const size_t bodies = size_t(L.max_agents + L.max_boxes + L.max_ramps);
  const size_t world = 26 * 1024 + bodies * 2150 + size_t(L.max_walls) * 200;
  return size_t(num_envs) * (L.state_bytes_per_env() + world);
}

}  // namespace hns::batch
