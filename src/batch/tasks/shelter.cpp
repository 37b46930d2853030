// Shelter construction (docs/game.md §9.3): a lone hider with 8 boxes (3 elongated) around a static cylinder
// in the empty arena must shield the cylinder from 100 rays cast from the arena's edges; every ray that still
// reaches it costs 0.001 per step. The cylinder is part of the scene (SceneConfig::target_diameter_*), and
// vision and lidar see it like any wall. The scene's preset is at the end.
#include <algorithm>
#include <cmath>

#include "batch/scenes.hpp"
#include "batch/tasks/task.hpp"

namespace hns::batch {
namespace {

// The shelter reward's rays (docs/game.md §9.3): 100 start points evenly spaced around the square
// [0.202, 5.798]² on the floor, 25 per side, each side's from its first corner (counter-clockwise from
// (0.202, 0.202)) up to but not including the next, aimed at the cylinder's centre. A ray reaches the
// cylinder when nothing else lies on the segment from its start to the cylinder; the segments are cast the
// other way, as one fan from the centre that skips the cylinder (nothing else can be inside it), so the 100
// rays share the vector kernel's blocks.
constexpr int kShelterRaysPerSide = 25;
constexpr int kShelterRays = 4 * kShelterRaysPerSide;
constexpr float kShelterEdgeLo = 0.202f, kShelterEdgeHi = 5.798f;  // m
constexpr float kShelterRayCost = 0.001f;                          // reward per ray that reaches the cylinder

}  // namespace

int shelter_rays_reaching(const Layout& L, const BatchState& s, const physics::World& world, int env) {
  const physics::Scene& scene = world.scene();
  if (!scene.has_target) return 0;
  const ShapesView shapes = shapes_view(L, s, world, env);
  const float cx = float(scene.target.x), cy = float(scene.target.y), cz = float(scene.target.z);
  alignas(64) float dx[kShelterRays], dy[kShelterRays], dz[kShelterRays], len[kShelterRays], t[kShelterRays];
  alignas(64) int32_t id[kShelterRays];
  for (int side = 0; side < 4; ++side) {
    for (int k = 0; k < kShelterRaysPerSide; ++k) {
      const int i = side * kShelterRaysPerSide + k;
      const float step = (kShelterEdgeHi - kShelterEdgeLo) * float(k) / kShelterRaysPerSide;
      const float up = kShelterEdgeLo + step, down = kShelterEdgeHi - step;
      const float ox = side == 0 ? up : side == 1 ? kShelterEdgeHi : side == 2 ? down : kShelterEdgeLo;
      const float oy = side == 0 ? kShelterEdgeLo : side == 1 ? up : side == 2 ? kShelterEdgeHi : down;
      const float ex = ox - cx, ey = oy - cy, ez = 0.0f - cz;
      len[i] = std::sqrt(ex * ex + ey * ey + ez * ez);
      dx[i] = ex / len[i], dy[i] = ey / len[i], dz[i] = ez / len[i];
    }
  }
  first_hits(shapes, RayFan{cx, cy, cz, dx, dy, dz, len, kShelterRays, shapes.cylinder_id(0)}, t, id);
  int reaching = 0;
  for (int i = 0; i < kShelterRays; ++i) reaching += id[i] < 0;
  return reaching;
}

namespace {

class Shelter final : public SingleAgentTask {
 public:
  // The scene has the cylinder.
  void validate(const physics::WorldConfig& world, const GameRules& rules) const override {
    SingleAgentTask::validate(world, rules);
    physics::check_field(world.scene.target_diameter_max > 0, "target_diameter_max",
                         world.scene.target_diameter_max, "must be > 0 in the shelter task (its cylinder)");
  }
  int hider_observation() const override { return 0; }  // a constant 0 (docs/game.md §9)

 protected:
  void reward(EnvRef& ref, float* reward) const override {
    const int rays = shelter_rays_reaching(ref.L, ref.s, ref.world, ref.index);
    std::fill_n(reward, ref.L.max_agents, -kShelterRayCost * float(rays));
  }
};

}  // namespace

// docs/game.md §9.3: 8 boxes (3 elongated) in the empty arena around a static cylinder of diameter U[1.5, 2]
// m, horizon 240.
BatchConfig shelter_scene() {
  static const Shelter task;
  BatchConfig c = transfer_scene(task, 240);
  physics::SceneConfig& s = c.world.scene;
  s.boxes = {8, 8};
  s.elongated = {3, 3};
  s.target_diameter_min = 1.5;
  s.target_diameter_max = 2.0;
  return c;
}

}  // namespace hns::batch
