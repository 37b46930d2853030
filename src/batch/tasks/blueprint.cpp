// Blueprint construction (docs/game.md §9.1): a lone hider in the empty arena must push cubes onto 1-4
// construction sites (0.5 m squares on the floor, always visible as the networks' fourth entity type). The
// reward pulls the cubes' corners onto the sites' corners; completing the blueprint pays 3 per site and
// absorbs the rest of the episode (task_complete, SingleAgentTask). The scene's preset is at the end.
#include <algorithm>
#include <cmath>
#include <limits>

#include "batch/scenes.hpp"
#include "batch/tasks/task.hpp"

namespace hns::batch {
namespace {

// The reward (docs/game.md §9.1). Box corners are the middles of a box's vertical edges, (±sx/2, ±sy/2, 0)
// from its centre turned by its yaw (tilt is ignored: the batch mirrors yaw only); a site's corners are
// (±0.25, ±0.25, 0) from its centre. Dense: for each site corner, the smooth minimum over every box corner of
// the distance, sum d e^(αd) / sum e^(αd) with α = -1.5; the reward is -0.05 x their mean. Completion: every
// site has a box centre within 0.1 m of its centre and every site corner a box corner within 0.1 m; it pays 3
// per site (on top of that step's dense reward) and sets task_complete.
constexpr double kBlueprintAlpha = -1.5;
constexpr double kBlueprintDenseScale = 0.05;
constexpr double kBlueprintRadius = 0.1;      // m
constexpr double kBlueprintSiteReward = 3.0;  // per site, on completion

void blueprint_rewards(EnvRef& ref, float* reward) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const int nb = ref.world.num_boxes();
  const size_t eb = size_t(env) * L.max_boxes, ec = size_t(env) * L.construction_sites;
  constexpr double kSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
  auto box_corner = [&](int b, int k, double* out) {
    const float* p = s.box_pos.data() + (eb + b) * 3;
    const float* r = s.box_rot.data() + (eb + b) * 2;
    const float* sz = s.box_size.data() + (eb + b) * 3;
    const double lx = kSigns[k][0] * 0.5 * sz[0], ly = kSigns[k][1] * 0.5 * sz[1];
    out[0] = p[0] + r[0] * lx - r[1] * ly;
    out[1] = p[1] + r[1] * lx + r[0] * ly;
    out[2] = p[2];
  };
  auto dist = [](const double* a, const double* b) {
    return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                     (a[2] - b[2]) * (a[2] - b[2]));
  };
  double smooth_sum = 0.0;
  int site_corners = 0, sites = 0;
  bool complete = nb > 0;
  for (int c = 0; c < L.construction_sites; ++c) {
    if (s.site_exists[ec + c] == 0) continue;
    ++sites;
    const float* sp = s.site_pos.data() + (ec + c) * 3;
    const double centre[3] = {sp[0], sp[1], sp[2]};
    double nearest_centre = std::numeric_limits<double>::infinity();
    for (int b = 0; b < nb; ++b) {
      const float* p = s.box_pos.data() + (eb + b) * 3;
      const double box[3] = {p[0], p[1], p[2]};
      nearest_centre = std::min(nearest_centre, dist(centre, box));
    }
    complete = complete && nearest_centre < kBlueprintRadius;
    for (int k = 0; k < 4; ++k) {
      const double corner[3] = {centre[0] + kSigns[k][0] * 0.5 * physics::kSiteSize,
                                centre[1] + kSigns[k][1] * 0.5 * physics::kSiteSize, centre[2]};
      double num = 0.0, den = 0.0, nearest = std::numeric_limits<double>::infinity();
      for (int b = 0; b < nb; ++b) {
        for (int q = 0; q < 4; ++q) {
          double bc[3];
          box_corner(b, q, bc);
          const double d = dist(corner, bc), w = std::exp(kBlueprintAlpha * d);
          num += d * w;
          den += w;
          nearest = std::min(nearest, d);
        }
      }
      smooth_sum += den > 0.0 ? num / den : 0.0;
      ++site_corners;
      complete = complete && nearest < kBlueprintRadius;
    }
  }
  double r = site_corners > 0 ? -kBlueprintDenseScale * smooth_sum / site_corners : 0.0;
  if (complete && sites > 0) {
    r += kBlueprintSiteReward * sites;
    s.task_complete[env] = 1;
  }
  std::fill_n(reward, L.max_agents, float(r));
}

// Construction sites (docs/game.md §9.1): centre, then the corners (-,-), (+,-), (+,+), (-,+); always
// visible.
void observe_sites(EnvRef& ref) {
  const int env = ref.index;
  const Layout& L = ref.L;
  BatchState& s = ref.s;
  const int A = L.max_agents, C = L.max_sites, CS = L.construction_sites, SF = L.site_features;
  const size_t ea = size_t(env) * A;
  float* obs_sites = s.obs_sites.data() + ea * C * SF;
  uint8_t* mask_sites = s.mask_sites.data() + ea * C;
  uint8_t* value_mask_sites = s.value_mask_sites.data() + ea * C;
  for (int a = 0; a < ref.world.num_agents(); ++a) {
    for (int c = 0; c < CS; ++c) {
      const size_t i = size_t(env) * CS + c;
      if (s.site_exists[i] == 0) continue;
      float* out = obs_sites + (size_t(a) * C + c) * SF;
      const float* p = s.site_pos.data() + 3 * i;
      std::copy_n(p, 3, out);
      constexpr float kHalf = float(0.5 * physics::kSiteSize);
      constexpr float kSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
      for (int k = 0; k < 4; ++k) {
        out[3 + 3 * k] = p[0] + kSigns[k][0] * kHalf;
        out[4 + 3 * k] = p[1] + kSigns[k][1] * kHalf;
        out[5 + 3 * k] = p[2];
      }
      mask_sites[a * C + c] = 1;
      value_mask_sites[a * C + c] = 1;
    }
  }
}

class Blueprint final : public SingleAgentTask {
 public:
  // Agent 0, construction sites and boxes to put on them; no counting layout, no food. (Not
  // SingleAgentTask's checks: those refuse the sites.)
  void validate(const physics::WorldConfig& world, const GameRules& /*rules*/) const override {
    require_agent_zero(world);
    physics::check_field(world.scene.sites.min >= 1, "sites.min", world.scene.sites.min,
                         "must be >= 1 in the blueprint task (its construction sites)");
    physics::check_field(world.scene.boxes.min >= 1, "boxes.min", world.scene.boxes.min,
                         "must be >= 1 in the blueprint task (its building blocks)");
    refuse_counting_layout(world);
    refuse_food(world);
  }
  int hider_observation() const override { return 0; }  // a constant 0 (docs/game.md §9)
  // The episode's construction sites (the scene's), and their observation rows' source.
  void start_episode(EnvRef& ref, uint64_t /*episode*/) const override {
    const int env = ref.index;
    const Layout& L = ref.L;
    BatchState& s = ref.s;
    const physics::Scene& scene = ref.world.scene();
    const int nc = int(scene.sites.size());
    for (int c = 0; c < L.construction_sites; ++c) {
      float* p = s.site_pos.data() + (size_t(env) * L.construction_sites + c) * 3;
      p[0] = c < nc ? float(scene.sites[c].x) : 0.0f;
      p[1] = c < nc ? float(scene.sites[c].y) : 0.0f;
      p[2] = c < nc ? float(scene.sites[c].z) : 0.0f;
      s.site_exists[size_t(env) * L.construction_sites + c] = c < nc ? 1 : 0;
    }
  }
  void observe(EnvRef& ref) const override { observe_sites(ref); }

 protected:
  void reward(EnvRef& ref, float* reward) const override { blueprint_rewards(ref, reward); }
};

}  // namespace

// docs/game.md §9.1: 8 cubes and 1-4 construction sites in the empty arena, horizon 150.
BatchConfig blueprint_scene() {
  static const Blueprint task;
  BatchConfig c = transfer_scene(task, 150);
  c.world.scene.boxes = {8, 8};
  c.world.scene.sites = {1, 4};
  return c;
}

}  // namespace hns::batch
