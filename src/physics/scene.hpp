// Scene generation on the 30 x 30 placement grid (docs/game.md §1.3, §2.3-§2.6, §14.5). Pure grid logic, no ODE:
// walls (in cells and as physical boxes), doors, and the spawn positions and sizes of agents, boxes and
// ramps.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "physics/rng.hpp"

namespace hns::physics {

// Grid and arena constants (docs/game.md §1.1, §1.3).
inline constexpr int kGridSize = 30;                // cells per side
inline constexpr double kCellSize = 0.2;            // m
inline constexpr double kFloorSize = 6.0;           // m, arena covers [0, 6]^2
inline constexpr double kWallThickness = 0.1;       // m
inline constexpr double kInteriorWallHeight = 0.5;  // m
inline constexpr double kOuterWallHeight = 4.0;     // m
inline constexpr double kAgentRadius = 0.15;        // m
inline constexpr double kBoxSize = 0.5;             // m, cube edge and elongated box height
inline constexpr double kElongatedLong = 1.65;      // m
inline constexpr double kElongatedShort = 0.15;     // m
inline constexpr double kRampSize = 0.5;            // m, footprint edge and height
inline constexpr double kTargetHeight = 0.5;        // m, the shelter task's cylinder
inline constexpr double kSiteSize = 0.5;            // m, a blueprint construction site's square (a cube's)
inline constexpr double kFoodSize = 0.1;            // m, a food item's extent (docs/game.md §5.4: 1 x 1 cell)
// Quadrant: q_size = int(0.5 * grid size), the room walls' row and column.
inline constexpr int kQuadrantSize = 15;

// Wall layout of a scene. kVarTri: three door-less rooms (docs/game.md §9.2 'var_tri', the sequential-lock task).
// kCounting: the object-counting task's fixed stage (docs/transfer.md "Object counting"): two screens, the
// agent and the boxes at fixed spots, each box's side drawn per episode.
enum class Layout : uint8_t { kEmpty, kQuadrant, kRandomWalls, kVarTri, kCounting };

// The object-counting stage (kCounting), m and env steps. The agent stands at (3, 0.7) facing +y; box k
// starts at (3, kCountingRow0 + k * kCountingRowStep), and from step kCountingStart + k * kCountingInterval
// slides kCountingSpeed per step to x = 3 -/+ kCountingTravel (left / right), where the screens hide it.
inline constexpr double kCountingAgentX = 3.0, kCountingAgentY = 0.7;
inline constexpr double kCountingRow0 = 2.6, kCountingRowStep = 0.55;
inline constexpr int kCountingStart = 5, kCountingInterval = 8;
inline constexpr double kCountingSpeed = 0.2, kCountingTravel = 2.4;
// Box k's centre x after `step` env steps of an episode; side -1 = left, +1 = right.
double counting_box_x(int k, int step, int side);

// Parses "empty", "quadrant", "randomwalls", "var_tri"; throws ConfigError otherwise.
Layout parse_layout(const std::string& name);
const char* layout_name(Layout layout);

// Bad user configuration: the message names the field, the value and what is allowed.
class ConfigError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// Inclusive integer range [min, max], drawn uniformly per episode.
struct IntRange {
  int min = 0;
  int max = 0;
};

// Everything that shapes one episode's scene. Presets: SceneConfig::quadrant(), SceneConfig::full().
struct SceneConfig {
  Layout layout = Layout::kQuadrant;
  IntRange hiders{2, 2};     // agents of team 0, placed first
  IntRange seekers{2, 2};    // agents of team 1
  IntRange boxes{2, 2};      // all boxes, elongated included
  IntRange elongated{0, 0};  // elongated boxes among them (drawn up to the drawn box count)
  IntRange ramps{1, 1};
  IntRange rooms{1, 4};                 // randomwalls: room count
  double prob_outside_walls = 1.0;      // randomwalls: chance the outer walls are kept
  double p_door_dropout = 0.5;          // quadrant: chance one room wall has no door
  int door_size = 2;                    // cells
  bool hider_uniform_placement = true;  // quadrant: hiders anywhere (else inside the room)
  double together_radius = 0.0;         // m; > 0: agents after the first of a team spawn near it
  // The paper's intrinsic-motivation baselines restrict the initial locations to a quarter of the game area:
  // when set, every agent, box and ramp spawns in the quarter x, y in [0.2, 3.0] m (grid cells 1 .. 14),
  // whatever the layout's own rule (rooms, teams, together_radius). Sites, food and the cylinder keep theirs.
  bool spawn_quarter = false;
  // Shelter construction (docs/game.md §9.3): a static cylinder of this diameter range (m; 0 = no cylinder), placed
  // in the middle 70 % of the grid before the agents, seen by lidar and vision rays, not observed.
  double target_diameter_min = 0.0;
  double target_diameter_max = 0.0;
  // Blueprint construction (docs/game.md §9.1): construction sites, squares of kSiteSize placed by
  // uniform_placement_middle(0.85) (3 x 3 cells) before anything else, so nothing spawns on one. Not
  // physical: nothing collides with a site, and rays pass through it.
  IntRange sites{0, 0};
  // Food (docs/game.md §5.4): items of kFoodSize placed after the ramps, 1 cell each; not physical. In the quadrant
  // layout inside the room (quadrant_placement), else with food_middle > 0 by
  // uniform_placement_middle(food_middle) (the paper's centred square), else uniformly; with
  // food_together_radius > 0 the items after the first within ceil(r / 0.2) cells of it.
  IntRange food{0, 0};
  double food_middle = 0.0;
  double food_together_radius = 0.0;  // m
  int max_tries_per_object = 10;      // rejection placement tries per object (docs/game.md §2.5)
  int max_regenerations = 1000;       // whole-scene rebuilds before giving up with an error

  static SceneConfig quadrant();
  static SceneConfig full();
  static SceneConfig empty();
  // Throws ConfigError naming the first bad field.
  void validate() const;
  // Throws ConfigError if the generator cannot build a scene with every count at its maximum (with the
  // fewest and with the most elongated boxes) within max_regenerations rebuilds: counts that pass
  // validate()'s area bound but not random placement (12 cubes in the quadrant room). Costs a few scene
  // generations: call it once per run, not per world.
  void check_placeable() const;
};

// A wall between grid cells (x1, y1) and (x2, y2), inclusive, sharing x or y.
struct WallCells {
  int x1, y1, x2, y2;
  bool outer;  // outer walls are 4 m high, interior ones 0.5 m
};

// A static axis-aligned box: centre and half extents in m.
struct StaticBox {
  double cx, cy, cz;
  double hx, hy, hz;
};

// A door: its first and last cell (inclusive) on a wall.
struct DoorCells {
  int x1, y1, x2, y2;
};

// A rectangle of grid cells, [x0, x1) x [y0, y1): a room's free interior.
struct CellRect {
  int x0, y0, x1, y1;
};

// A movable body's spawn: centre (m) and full extents (m). Yaw is always 0 at spawn.
struct Spawn {
  double x, y, z;
  double sx, sy, sz;
};

struct Scene {
  Layout layout = Layout::kEmpty;
  bool outer_walls = true;
  std::vector<WallCells> walls;       // pieces after door splitting, >= 2 cells; no dropped outer walls
  std::vector<StaticBox> wall_boxes;  // the same walls as physical boxes (docs/game.md §1.3)
  std::vector<DoorCells> doors;
  std::vector<CellRect> rooms;  // var_tri: the two small rooms, then the large one (empty otherwise)
  int num_hiders = 0;
  int num_seekers = 0;
  std::vector<Spawn> agents;  // hiders first, then seekers
  std::vector<Spawn> boxes;   // x-elongated first, then y-elongated, then cubes (docs/game.md §2.6)
  int num_elongated = 0;
  std::vector<Spawn> ramps;
  bool has_target = false;  // shelter: the cylinder, centre and full extents (sx = sy = diameter)
  Spawn target{};
  // Blueprint's construction sites, centre at z = kSiteSize / 2, sx = sy = kSiteSize.
  std::vector<Spawn> sites;
  // Food items, centre at z = kFoodSize / 2, sx = sy = sz = kFoodSize.
  std::vector<Spawn> food;
  // kCounting: the side each box goes to, -1 left or +1 right (one per box).
  std::vector<int8_t> sides;
  int regenerations = 0;  // whole-scene rebuilds this scene needed
};

// Generates one scene from the stream. Reuses `out`'s capacity. Throws std::runtime_error if no valid
// scene was found within config.max_regenerations rebuilds (impossible configurations fail validate()).
void generate_scene(const SceneConfig& config, Rng& rng, Scene& out);

// A new spot for a food item that respawns elsewhere (dynamic food): a cell drawn by the scene's food
// placement (ignoring occupancy: boxes move during an episode), jittered like a spawn. Returns x, y (m).
std::pair<double, double> food_respawn_spot(const SceneConfig& config, Rng& rng);

}  // namespace hns::physics
