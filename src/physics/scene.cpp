// Scene generation (docs/game.md §1.3, §2.3-§2.6, §14.5).
//
// One attempt: draw the counts -> build the walls and doors on the 30 x 30 grid (quadrant, random rooms or
// the bare arena) -> mark the wall cells -> turn the wall pieces into physical boxes -> rejection-place
// agents (hiders, then seekers), boxes and ramps. A failed placement, or random walls that cannot be split
// into the drawn room count, throws the attempt away and rebuilds the whole scene from the same, advanced
// stream.
#include "physics/scene.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <utility>

#include "physics/scene_limits.hpp"

namespace hns::physics {
namespace {

constexpr int kMinRoomSize = 6;  // random walls: attachment points on one side of a wall are > 6 cells apart
constexpr int kSplitTries = 10;  // random walls: attempts per new interior wall (choose_new_split)
constexpr int kRoomFailures = 10;  // random walls: restarts from the outer walls before the scene is rebuilt

using namespace scene_limits;

// ---------------------------------------------------------------------------------------------------------------
// Occupancy grid, indexed [x][y]. Cells outside the grid count as occupied.
class Grid {
 public:
  void clear() { cells_.fill(0); }
  bool free(int i, int j, int cx, int cy) const {
    if (i < 0 || j < 0 || i + cx > kGridSize || j + cy > kGridSize) return false;
    for (int x = i; x < i + cx; ++x) {
      for (int y = j; y < j + cy; ++y) {
        if (cells_[x * kGridSize + y]) return false;
      }
    }
    return true;
  }
  void mark(int i, int j, int cx, int cy) {
    for (int x = i; x < i + cx; ++x) {
      for (int y = j; y < j + cy; ++y) cells_[x * kGridSize + y] = 1;
    }
  }
  // Every cell of the wall from p1 to p2 inclusive.
  void mark_wall(const WallCells& w) {
    mark(std::min(w.x1, w.x2), std::min(w.y1, w.y2), std::abs(w.x2 - w.x1) + 1, std::abs(w.y2 - w.y1) + 1);
  }

 private:
  std::array<uint8_t, size_t{kGridSize} * kGridSize> cells_{};
};

// ---------------------------------------------------------------------------------------------------------------
// Walls → physical boxes (docs/game.md §1.3): from the centre of p1 to the centre of p2, shortened by half
// the wall thickness at each end, centred on the cell-centre line. (Pieces of one cell, which would have no
// physical length, are never made.)
void add_wall_box(const WallCells& w, std::vector<StaticBox>& boxes) {
  const int cells_x = std::abs(w.x2 - w.x1), cells_y = std::abs(w.y2 - w.y1);
  const double length = (cells_x + cells_y) * kCellSize - kWallThickness;
  if (length <= 1e-9) return;
  const double height = w.outer ? kOuterWallHeight : kInteriorWallHeight;
  const double half_thick = 0.5 * kWallThickness;
  StaticBox b;
  b.cx = 0.5 * (w.x1 + w.x2 + 1) * kCellSize;
  b.cy = 0.5 * (w.y1 + w.y2 + 1) * kCellSize;
  b.cz = 0.5 * height;
  b.hx = cells_x > 0 ? 0.5 * length : half_thick;
  b.hy = cells_y > 0 ? 0.5 * length : half_thick;
  b.hz = 0.5 * height;
  boxes.push_back(b);
}

// The four outer walls, corner cells shared.
constexpr std::array<WallCells, 4> kOuterWalls = {{
    {0, 0, 0, kGridSize - 1, true},
    {0, 0, kGridSize - 1, 0, true},
    {kGridSize - 1, 0, kGridSize - 1, kGridSize - 1, true},
    {0, kGridSize - 1, kGridSize - 1, kGridSize - 1, true},
}};

// Cuts a door of `door` cells into wall w (p1 <= p2), `offset` cells from p1, and appends the remaining
// pieces [p1, offset - 1] and [offset + door, p2] and the door. A piece of a single cell is dropped, as the
// original does: it would have no physical length, and its cell (where the wall meets another) stays free
// unless that other wall holds it.
void split_for_door(const WallCells& w, int offset, int door, std::vector<WallCells>& pieces,
                    std::vector<DoorCells>& doors) {
  const int dx = w.x2 > w.x1 ? 1 : 0, dy = w.y2 > w.y1 ? 1 : 0;
  const int first = offset, last = offset + door - 1;  // door cells, measured from p1
  const int length = (w.x2 - w.x1) + (w.y2 - w.y1);
  if (first - 1 > 0)
    pieces.push_back({w.x1, w.y1, w.x1 + dx * (first - 1), w.y1 + dy * (first - 1), w.outer});
  if (last + 1 < length)
    pieces.push_back({w.x1 + dx * (last + 1), w.y1 + dy * (last + 1), w.x2, w.y2, w.outer});
  doors.push_back({w.x1 + dx * first, w.y1 + dy * first, w.x1 + dx * last, w.y1 + dy * last});
}

// ---------------------------------------------------------------------------------------------------------------
// Random rooms (docs/game.md §2.4).
struct Point {
  int x, y;
};

// A wall of the random-rooms builder, p1 <= p2. edges[0] holds the points where perpendicular walls leave it
// toward lower coordinates (below / left), edges[1] toward higher ones; both start with the wall's endpoints.
struct RoomWall {
  Point p1, p2;
  bool vertical;
  int length;  // cells from p1 to p2
  std::array<std::array<Point, kMaxEdges>, 2> edges;
  std::array<int, 2> num_edges;

  static RoomWall make(Point a, Point b) {
    RoomWall w;
    const bool swap = b.x < a.x || b.y < a.y;
    w.p1 = swap ? b : a;
    w.p2 = swap ? a : b;
    w.vertical = w.p1.x == w.p2.x;
    w.length = (w.p2.x - w.p1.x) + (w.p2.y - w.p1.y);
    for (int side = 0; side < 2; ++side) {
      w.edges[side][0] = w.p1;
      w.edges[side][1] = w.p2;
      w.num_edges[side] = 2;
    }
    return w;
  }
  int across() const { return vertical ? p1.x : p1.y; }
  int along(Point p) const { return vertical ? p.y : p.x; }
  // The point lies on the wall, endpoints included.
  bool touches(Point p) const {
    return vertical ? p.x == p1.x && p.y >= p1.y && p.y <= p2.y : p.y == p1.y && p.x >= p1.x && p.x <= p2.x;
  }
  // Strict crossing of two perpendicular walls: touching at an endpoint is allowed.
  bool crosses(const RoomWall& o) const {
    if (vertical == o.vertical) return false;
    const RoomWall& v = vertical ? *this : o;
    const RoomWall& h = vertical ? o : *this;
    return h.p1.x < v.p1.x && v.p1.x < h.p2.x && v.p1.y < h.p1.y && h.p1.y < v.p2.y;
  }
  void add_edge(int side, Point p) {
    if (num_edges[side] < kMaxEdges) edges[side][num_edges[side]++] = p;
  }
  // Records where perpendicular wall w meets this wall: w leaves toward higher coordinates from its p1.
  void record_attachment(const RoomWall& w) {
    if (w.vertical == vertical) return;
    if (touches(w.p1)) {
      add_edge(1, w.p1);
    } else if (touches(w.p2)) {
      add_edge(0, w.p2);
    }
  }
};

class RoomBuilder {
 public:
  // Builds rooms - 1 interior walls; false after kRoomFailures restarts.
  bool build(int rooms, Rng& rng) {
    reset();
    int failures = 0;
    while (num_walls_ < rooms + 3) {
      if (!add_split(rng)) {
        reset();
        if (++failures >= kRoomFailures) return false;
      }
    }
    return true;
  }

  // Appends the wall pieces (outer walls first, then interior walls split at their doors) and the doors.
  // Each interior wall gets at most one door, inside a stretch of >= door + 1 cells between attachment
  // points.
  void emit(int door, Rng& rng, std::vector<WallCells>& pieces, std::vector<DoorCells>& doors) const {
    pieces.insert(pieces.end(), kOuterWalls.begin(), kOuterWalls.end());
    for (int k = 4; k < num_walls_; ++k) {
      const RoomWall& w = walls_[k];
      const WallCells cells{w.p1.x, w.p1.y, w.p2.x, w.p2.y, false};
      // Attachment points along the wall, sorted and unique.
      std::array<int, size_t{2} * kMaxEdges> at;
      int n = 0;
      for (int side = 0; side < 2; ++side) {
        for (int e = 0; e < w.num_edges[side]; ++e) at[n++] = w.along(w.edges[side][e]);
      }
      std::sort(at.begin(), at.begin() + n);
      n = static_cast<int>(std::unique(at.begin(), at.begin() + n) - at.begin());
      std::array<int, size_t{2} * kMaxEdges> stretches;  // index of the stretch's first attachment point
      int num_stretches = 0;
      for (int e = 0; e + 1 < n; ++e) {
        if (at[e + 1] - at[e] >= door + 1) stretches[num_stretches++] = e;
      }
      if (num_stretches == 0) {
        pieces.push_back(cells);
        continue;
      }
      const int e = stretches[rng.uniform_int(0, num_stretches)];
      const int start = rng.uniform_int(1, at[e + 1] - at[e] - door + 1);
      split_for_door(cells, at[e] - w.along(w.p1) + start, door, pieces, doors);
    }
  }

 private:
  void reset() {
    num_walls_ = 0;
    for (const WallCells& o : kOuterWalls) walls_[num_walls_++] = RoomWall::make({o.x1, o.y1}, {o.x2, o.y2});
  }

  // choose_new_split: up to kSplitTries random source walls; from each, one perpendicular proposal toward
  // every other parallel wall; one surviving proposal is kept.
  bool add_split(Rng& rng) {
    std::array<RoomWall, kMaxRoomWalls> proposals;
    for (int attempt = 0; attempt < kSplitTries; ++attempt) {
      const RoomWall& w1 = walls_[rng.uniform_int(0, num_walls_)];
      int num_proposals = 0;
      for (int k = 0; k < num_walls_; ++k) {
        const RoomWall& w2 = walls_[k];
        if (&w2 == &w1 || w2.vertical != w1.vertical) continue;
        RoomWall candidate;
        if (propose(w1, w2, rng, candidate) && !crosses_any(candidate))
          proposals[num_proposals++] = candidate;
      }
      if (num_proposals > 0) {
        add_wall(proposals[rng.uniform_int(0, num_proposals)]);
        return true;
      }
    }
    return false;
  }

  // connect_walls: a perpendicular wall from a random interior point of w1 to w2's line. Valid if it ends on
  // w2 and its start is more than kMinRoomSize cells from every attachment point on that side of w1.
  static bool propose(const RoomWall& w1, const RoomWall& w2, Rng& rng, RoomWall& out) {
    if (w1.length < 2) return false;
    const int offset = rng.uniform_int(1, w1.length);
    const Point start = w1.vertical ? Point{w1.p1.x, w1.p1.y + offset} : Point{w1.p1.x + offset, w1.p1.y};
    const Point end = w1.vertical ? Point{w2.p1.x, start.y} : Point{start.x, w2.p1.y};
    if (w2.across() == w1.across() || !w2.touches(end)) return false;
    const int side = w2.across() > w1.across() ? 1 : 0;
    for (int e = 0; e < w1.num_edges[side]; ++e) {
      const int dx = start.x - w1.edges[side][e].x, dy = start.y - w1.edges[side][e].y;
      if (dx * dx + dy * dy <= kMinRoomSize * kMinRoomSize) return false;  // Euclidean distance <= 6
    }
    out = RoomWall::make(start, end);
    return true;
  }

  bool crosses_any(const RoomWall& w) const {
    for (int k = 0; k < num_walls_; ++k) {
      if (w.crosses(walls_[k])) return true;
    }
    return false;
  }

  void add_wall(RoomWall w) {
    for (int k = 0; k < num_walls_; ++k) {
      walls_[k].record_attachment(w);
      w.record_attachment(walls_[k]);
    }
    walls_[num_walls_++] = w;
  }

  std::array<RoomWall, kMaxRoomWalls> walls_;
  int num_walls_ = 0;
};

// ---------------------------------------------------------------------------------------------------------------
// var_tri (docs/game.md §9.2): a full-length wall at cell s1 = int(30 U(0.4, 0.6)), vertical or horizontal
// with p = 0.5, and a perpendicular wall at cell s2 = int(30 U(0.4, 0.6)) from it to the outer wall on its
// low or high side with p = 0.5. No doors: three closed rooms, about a quarter, a quarter and a half of the
// arena. Appends the two walls and the rooms' free cells (the two quarter rooms first, then the half).
void var_tri_walls(Rng& rng, std::vector<WallCells>& walls, std::vector<CellRect>& rooms) {
  constexpr int kLast = kGridSize - 1;  // the outer walls' row and column
  const int s1 = static_cast<int>(kGridSize * rng.uniform(0.4, 0.6));
  const int s2 = static_cast<int>(kGridSize * rng.uniform(0.4, 0.6));
  const bool vertical = rng.bernoulli(0.5);
  const bool high_side = rng.bernoulli(0.5);
  // Built for a vertical first wall (x = s1); a horizontal one swaps x and y.
  WallCells first{s1, 0, s1, kLast, false};
  WallCells second = high_side ? WallCells{s1, s2, kLast, s2, false} : WallCells{0, s2, s1, s2, false};
  const int split_lo = high_side ? s1 + 1 : 1, split_hi = high_side ? kLast : s1;  // the split side's cells
  const int whole_lo = high_side ? 1 : s1 + 1, whole_hi = high_side ? s1 : kLast;
  CellRect small_a{split_lo, 1, split_hi, s2}, small_b{split_lo, s2 + 1, split_hi, kLast};
  CellRect large{whole_lo, 1, whole_hi, kLast};
  if (!vertical) {
    auto swap_wall = [](WallCells& w) { w = WallCells{w.y1, w.x1, w.y2, w.x2, w.outer}; };
    auto swap_rect = [](CellRect& r) { r = CellRect{r.y0, r.x0, r.y1, r.x1}; };
    swap_wall(first), swap_wall(second);
    swap_rect(small_a), swap_rect(small_b), swap_rect(large);
  }
  walls.push_back(first);
  walls.push_back(second);
  rooms.assign({small_a, small_b, large});
}

// ---------------------------------------------------------------------------------------------------------------
// Placement functions (docs/game.md §2.5). Bounds are numpy-style: uniform_int(lo, hi) draws lo … hi - 1.
enum class Placement : uint8_t {
  kUniform,
  kQuadrant,
  kOutsideQuadrant,
  kCloseTo,
  kInRoom,
  kMiddle,
  kSpawnQuarter
};
// Shelter's cylinder: uniform_placement_middle(0.7); blueprint's sites: uniform_away_from_walls (docs/game.md
// §9.1).
constexpr double kMiddleFraction = 0.7;
constexpr double kSiteMiddleFraction = 0.85;

struct Cell {
  int i = 0, j = 0;
};

Cell propose_cell(Placement p, int cx, int cy, Cell anchor, int radius_cells, const CellRect& room,
                  double middle, Rng& rng) {
  constexpr int kG = kGridSize, kQ = kQuadrantSize;  // G and q of docs/game.md §2.5
  switch (p) {
    case Placement::kMiddle: {  // uniform_placement_middle(f), f = middle (docs/game.md §2.5)
      auto range = [middle](int c) {
        const double f = middle;
        const int lo = static_cast<int>((kG - c) * (1 - f) / 2 + f),
                  hi = static_cast<int>((kG - c) * (1 + f) / 2 - f);
        return std::pair<int, int>{lo, std::max(lo + 1, hi)};
      };
      const auto [xlo, xhi] = range(cx);
      const auto [ylo, yhi] = range(cy);
      const int i = rng.uniform_int(xlo, xhi);
      return {i, rng.uniform_int(ylo, yhi)};
    }
    case Placement::kInRoom: {
      const int i = rng.uniform_int(room.x0, std::max(room.x0, room.x1 - cx) + 1);
      return {i, rng.uniform_int(room.y0, std::max(room.y0, room.y1 - cy) + 1)};
    }
    case Placement::kSpawnQuarter: {  // footprint inside cells 1 .. kQ - 1: x, y in [0.2, 3.0] m
      const int i = rng.uniform_int(1, std::max(2, kQ - cx + 1));
      return {i, rng.uniform_int(1, std::max(2, kQ - cy + 1))};
    }
    case Placement::kQuadrant: {
      const int i = rng.uniform_int(kG - kQ, kG - cx - 1);
      return {i, rng.uniform_int(1, kQ - cy - 1)};
    }
    case Placement::kOutsideQuadrant: {
      const int region = rng.uniform_int(0, 3);
      const int i = region < 2 ? rng.uniform_int(1, kQ - cx - 1) : rng.uniform_int(kQ, kG - cx - 1);
      const int j = region == 0 ? rng.uniform_int(1, kQ - cy - 1) : rng.uniform_int(kQ, kG - cy - 1);
      return {i, j};
    }
    case Placement::kCloseTo: {
      const int r = radius_cells;
      const int i = rng.uniform_int(std::max(1, anchor.i - r), std::min(kG - 1, anchor.i + r));
      return {i, rng.uniform_int(std::max(1, anchor.j - r), std::min(kG - 1, anchor.j + r))};
    }
    case Placement::kUniform:
    default: {
      const int i = rng.uniform_int(1, kG - cx - 1);
      return {i, rng.uniform_int(1, kG - cy - 1)};
    }
  }
}

// What one object needs from the rejection placement.
struct Request {
  Placement placement = Placement::kUniform;
  double sx = 0, sy = 0, sz = 0;    // full extents, m
  double z = 0;                     // spawn height of the centre, m
  Cell anchor;                      // kCloseTo: the anchor's spawn cell
  int radius_cells = 0;             // kCloseTo: r = ceil(radius / 0.2)
  CellRect room{};                  // kInRoom: the room's free cells
  double middle = kMiddleFraction;  // kMiddle: the fraction f
};

// A food item's request (docs/game.md §5.4): 1 cell, in the quadrant room, the middle fraction, or anywhere.
Request food_request(const SceneConfig& config) {
  Request req;
  req.placement = config.layout == Layout::kQuadrant ? Placement::kQuadrant
                  : config.food_middle > 0           ? Placement::kMiddle
                                                     : Placement::kUniform;
  req.middle = config.food_middle;
  req.sx = req.sy = req.sz = kFoodSize;
  req.z = 0.5 * kFoodSize;
  return req;
}

// rejection_placement: up to `tries` proposals; the first whose cells are all free is jittered inside its
// cells, marked and returned.
bool place(const Request& req, int tries, Grid& grid, Rng& rng, Spawn& spawn, Cell& cell) {
  const int cx = footprint_cells(req.sx), cy = footprint_cells(req.sy);
  for (int t = 0; t < tries; ++t) {
    const Cell c =
        propose_cell(req.placement, cx, cy, req.anchor, req.radius_cells, req.room, req.middle, rng);
    if (!grid.free(c.i, c.j, cx, cy)) continue;
    const double corner_x = c.i * kCellSize + rng.uniform(0.0, cx * kCellSize - req.sx);
    const double corner_y = c.j * kCellSize + rng.uniform(0.0, cy * kCellSize - req.sy);
    spawn = Spawn{corner_x + 0.5 * req.sx, corner_y + 0.5 * req.sy, req.z, req.sx, req.sy, req.sz};
    grid.mark(c.i, c.j, cx, cy);
    cell = c;
    return true;
  }
  return false;
}

// ---------------------------------------------------------------------------------------------------------------
// Why the last attempt failed, for the final error message.
struct Failure {
  const char* object = "";  // "hider", "seeker", "box", "ramp", "target", "site" or "rooms"
  int index = 0;
  const char* kind = "";  // agent, box kind or ramp
  int cx = 0, cy = 0;
  Placement placement = Placement::kUniform;
  int rooms = 0;
};

const char* placement_region(Placement p) {
  switch (p) {
    case Placement::kQuadrant:
      return "inside the quadrant room";
    case Placement::kOutsideQuadrant:
      return "outside the quadrant room";
    case Placement::kCloseTo:
      return "near its team's first agent";
    case Placement::kInRoom:
      return "inside its room";
    case Placement::kMiddle:
      return "in the middle of the arena";
    case Placement::kSpawnQuarter:
      return "in the spawn quarter (x, y in [0.2, 3.0] m)";
    case Placement::kUniform:
    default:
      return "anywhere in the arena";
  }
}

struct Counts {
  int hiders = 0, seekers = 0, boxes = 0, elongated = 0, x_aligned = 0, ramps = 0, sites = 0, food = 0;
};

int draw(const IntRange& r, Rng& rng) {
  return rng.uniform_int(r.min, r.max + 1);
}

// Counts of one attempt (docs/game.md §2.6), and the scene emptied for them. With fewer boxes than
// elongated.min, every box is elongated.
void draw_counts(const SceneConfig& config, Rng& rng, Counts& n, Scene& out) {
  n.hiders = draw(config.hiders, rng);
  n.seekers = draw(config.seekers, rng);
  n.boxes = draw(config.boxes, rng);
  const int elongated_hi = std::min(config.elongated.max, n.boxes);
  n.elongated = rng.uniform_int(std::min(config.elongated.min, elongated_hi), elongated_hi + 1);
  n.x_aligned = rng.uniform_int(0, n.elongated + 1);
  n.ramps = draw(config.ramps, rng);
  // No draw without sites or food: other scenes keep their streams.
  n.sites = config.sites.max > 0 ? draw(config.sites, rng) : 0;
  n.food = config.food.max > 0 ? draw(config.food, rng) : 0;

  out.layout = config.layout;
  out.outer_walls = true;
  out.walls.clear();
  out.wall_boxes.clear();
  out.doors.clear();
  out.rooms.clear();
  out.agents.clear();
  out.boxes.clear();
  out.ramps.clear();
  out.has_target = false;
  out.sites.clear();
  out.food.clear();
  out.sides.clear();
  out.num_hiders = n.hiders;
  out.num_seekers = n.seekers;
  out.num_elongated = n.elongated;
}

// Walls and doors of the layout; out.walls receives every piece first, and dropped outer walls are removed
// entirely (docs/game.md §2.4). False (with `fail` filled) if the random walls could not be built.
bool build_walls(const SceneConfig& config, Rng& rng, Scene& out, Failure& fail) {
  const int door = config.door_size;
  switch (config.layout) {
    case Layout::kEmpty:
      out.walls.insert(out.walls.end(), kOuterWalls.begin(), kOuterWalls.end());
      break;
    case Layout::kQuadrant: {
      // docs/game.md §2.3: a vertical and a horizontal room wall; with p_door_dropout one of them has no
      // door.
      out.walls.insert(out.walls.end(), kOuterWalls.begin(), kOuterWalls.end());
      const std::array<WallCells, 2> room = {{
          {kQuadrantSize, 0, kQuadrantSize, kQuadrantSize, false},
          {kQuadrantSize, kQuadrantSize, kGridSize - 1, kQuadrantSize, false},
      }};
      const int no_door = rng.bernoulli(config.p_door_dropout) ? rng.uniform_int(0, 2) : -1;
      for (int k = 0; k < 2; ++k) {
        if (k == no_door) {
          out.walls.push_back(room[k]);
          continue;
        }
        const int length = (room[k].x2 - room[k].x1) + (room[k].y2 - room[k].y1);
        split_for_door(room[k], rng.uniform_int(1, length - door + 1), door, out.walls, out.doors);
      }
      break;
    }
    case Layout::kRandomWalls: {
      RoomBuilder builder;
      const int rooms = draw(config.rooms, rng);
      if (!builder.build(rooms, rng)) {
        fail = Failure{"rooms", 0, "", 0, 0, Placement::kUniform, rooms};
        return false;
      }
      builder.emit(door, rng, out.walls, out.doors);
      out.outer_walls = rng.bernoulli(config.prob_outside_walls);
      break;
    }
    case Layout::kVarTri:
      out.walls.insert(out.walls.end(), kOuterWalls.begin(), kOuterWalls.end());
      var_tri_walls(rng, out.walls, out.rooms);
      break;
    case Layout::kCounting:
      // Two screens in row 9 (y 1.85 .. 1.95 m, interior height), x 0.15 .. 2.45 m and 3.55 .. 5.85 m: the
      // gap between them shows the boxes' column to the agent and hides both ends of their rows.
      out.walls.insert(out.walls.end(), kOuterWalls.begin(), kOuterWalls.end());
      out.walls.push_back({0, 9, 12, 9, false});
      out.walls.push_back({17, 9, 29, 9, false});
      break;
  }
  if (!out.outer_walls) {
    out.walls.erase(
        std::remove_if(out.walls.begin(), out.walls.end(), [](const WallCells& w) { return w.outer; }),
        out.walls.end());
  }
  return true;
}

// The counting layout's fixed spots: the agent at its place, box k in row k; only the sides are drawn.
void place_counting(const Counts& n, Rng& rng, Scene& out) {
  out.num_hiders = 1;
  out.num_seekers = 0;
  out.num_elongated = 0;
  out.agents.push_back(
      {kCountingAgentX, kCountingAgentY, kAgentRadius, 2 * kAgentRadius, 2 * kAgentRadius, 2 * kAgentRadius});
  for (int k = 0; k < n.boxes; ++k) {
    out.boxes.push_back({kCountingAgentX, kCountingRow0 + k * kCountingRowStep, 0.5 * kBoxSize, kBoxSize,
                         kBoxSize, kBoxSize});
    out.sides.push_back(rng.bernoulli(0.5) ? int8_t{-1} : int8_t{1});
  }
}

// The rejection placement of one attempt's objects, in the fixed order of docs/game.md §2.2: shelter's
// cylinder and blueprint's sites before anything movable, then agents, boxes, ramps and food. Each step
// returns false (with `fail` filled) when an object found no free cells.
struct Placer {
  const SceneConfig& config;
  const Counts& n;
  Rng& rng;
  Grid& grid;
  Scene& out;
  Failure& fail;
  int tries = config.max_tries_per_object;

  // Shelter's cylinder (its diameter drawn first).
  bool target() {
    if (config.target_diameter_max <= 0) return true;
    Request req;
    req.placement = Placement::kMiddle;
    req.sx = req.sy = rng.uniform(config.target_diameter_min, config.target_diameter_max);
    req.sz = kTargetHeight;
    req.z = 0.5 * kTargetHeight;
    Cell cell;
    if (!place(req, tries, grid, rng, out.target, cell)) {
      const int c = footprint_cells(req.sx);
      fail = Failure{"target", 0, "cylinder", c, c, req.placement, 0};
      return false;
    }
    out.has_target = true;
    return true;
  }

  // Blueprint's construction sites.
  bool sites() {
    Spawn spawn;
    Cell cell;
    for (int k = 0; k < n.sites; ++k) {
      Request req;
      req.placement = Placement::kMiddle;
      req.middle = kSiteMiddleFraction;
      req.sx = req.sy = kSiteSize;
      req.z = 0.5 * kSiteSize;
      if (!place(req, tries, grid, rng, spawn, cell)) {
        const int c = footprint_cells(req.sx);
        fail = Failure{"site", k, "construction site", c, c, req.placement, 0};
        return false;
      }
      spawn.sz = 0.0;
      out.sites.push_back(spawn);
    }
    return true;
  }

  // Agents (docs/game.md §2.5): hiders, then seekers; after the first of a team, near it when
  // together_radius > 0.
  bool agents() {
    const bool quadrant = config.layout == Layout::kQuadrant;
    const int together_cells =
        std::min(kGridSize, static_cast<int>(std::ceil(config.together_radius / kCellSize - 1e-9)));
    Spawn spawn;
    Cell cell, first_of_team;
    for (int a = 0; a < n.hiders + n.seekers; ++a) {
      const bool hider = a < n.hiders;
      const int in_team = hider ? a : a - n.hiders;
      Request req;
      req.sx = req.sy = req.sz = 2.0 * kAgentRadius;
      req.z = kAgentRadius;
      if (in_team > 0 && config.together_radius > 0) {
        req.placement = Placement::kCloseTo;
        req.anchor = first_of_team;
        req.radius_cells = together_cells;
      } else if (quadrant) {
        req.placement = hider ? (config.hider_uniform_placement ? Placement::kUniform : Placement::kQuadrant)
                              : Placement::kOutsideQuadrant;
      }
      if (config.spawn_quarter) req.placement = Placement::kSpawnQuarter;
      if (!place(req, tries, grid, rng, spawn, cell)) {
        const int c = footprint_cells(req.sx);
        fail = Failure{hider ? "hider" : "seeker", in_team, "agent", c, c, req.placement, 0};
        return false;
      }
      if (in_team == 0) first_of_team = cell;
      out.agents.push_back(spawn);
    }
    return true;
  }

  // Boxes (docs/game.md §2.6): x-elongated, y-elongated, then cubes; inside the room in the quadrant game.
  bool boxes() {
    const bool quadrant = config.layout == Layout::kQuadrant;
    Spawn spawn;
    Cell cell;
    for (int b = 0; b < n.boxes; ++b) {
      Request req;
      req.placement = config.spawn_quarter ? Placement::kSpawnQuarter
                      : quadrant           ? Placement::kQuadrant
                                           : Placement::kUniform;
      const char* kind = "cube";
      if (b < n.x_aligned) {
        req.sx = kElongatedLong, req.sy = kElongatedShort, kind = "x-elongated";
      } else if (b < n.elongated) {
        req.sx = kElongatedShort, req.sy = kElongatedLong, kind = "y-elongated";
      } else {
        req.sx = req.sy = kBoxSize;
      }
      req.sz = kBoxSize;
      req.z = 0.5 * kBoxSize;
      if (!place(req, tries, grid, rng, spawn, cell)) {
        fail = Failure{"box", b, kind, footprint_cells(req.sx), footprint_cells(req.sy), req.placement, 0};
        return false;
      }
      out.boxes.push_back(spawn);
    }
    return true;
  }

  // Ramps: uniform; in var_tri, ramp r in room r mod 3 (the original's tri_placement).
  bool ramps() {
    Spawn spawn;
    Cell cell;
    for (int r = 0; r < n.ramps; ++r) {
      Request req;
      if (!out.rooms.empty()) {
        req.placement = Placement::kInRoom;
        req.room = out.rooms[size_t(r) % out.rooms.size()];
      }
      if (config.spawn_quarter) req.placement = Placement::kSpawnQuarter;
      req.sx = req.sy = req.sz = kRampSize;
      req.z = 0.5 * kRampSize;
      if (!place(req, tries, grid, rng, spawn, cell)) {
        const int c = footprint_cells(kRampSize);
        fail = Failure{"ramp", r, "ramp", c, c, req.placement, 0};
        return false;
      }
      out.ramps.push_back(spawn);
    }
    return true;
  }

  // Food (docs/game.md §5.4), after the ramps; the items after the first near it with
  // food_together_radius.
  bool food() {
    Spawn spawn;
    Cell cell, first_food;
    const int food_cells =
        std::min(kGridSize, static_cast<int>(std::ceil(config.food_together_radius / kCellSize - 1e-9)));
    for (int f = 0; f < n.food; ++f) {
      Request req = food_request(config);
      if (f > 0 && config.food_together_radius > 0) {
        req.placement = Placement::kCloseTo;
        req.anchor = first_food;
        req.radius_cells = food_cells;
      }
      if (!place(req, tries, grid, rng, spawn, cell)) {
        fail = Failure{"food", f, "food item", 1, 1, req.placement, 0};
        return false;
      }
      if (f == 0) first_food = cell;
      out.food.push_back(spawn);
    }
    return true;
  }
};

// One attempt at a full scene; false (with `fail` filled) if anything could not be built or placed.
bool try_generate(const SceneConfig& config, Rng& rng, Scene& out, Counts& n, Failure& fail) {
  draw_counts(config, rng, n, out);
  if (!build_walls(config, rng, out, fail)) return false;
  // Occupancy is every cell of every remaining wall piece (docs/game.md §2.4, add_walls_to_grid after the
  // drop).
  Grid grid;
  grid.clear();
  for (const WallCells& w : out.walls) grid.mark_wall(w);
  for (const WallCells& w : out.walls) add_wall_box(w, out.wall_boxes);
  if (config.layout == Layout::kCounting) {
    place_counting(n, rng, out);
    return true;
  }
  Placer placer{config, n, rng, grid, out, fail};
  return placer.target() && placer.sites() && placer.agents() && placer.boxes() && placer.ramps() &&
         placer.food();
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
void generate_scene(const SceneConfig& config, Rng& rng, Scene& out) {
  config.validate();
  Counts counts;
  Failure fail;
  for (int attempt = 0; attempt <= config.max_regenerations; ++attempt) {
    if (try_generate(config, rng, out, counts, fail)) {
      out.regenerations = attempt;
      return;
    }
  }
  std::ostringstream msg;
  msg << "scene generation failed after " << config.max_regenerations << " rebuilds (layout "
      << layout_name(config.layout) << "); the last attempt had " << counts.hiders << " hiders, "
      << counts.seekers << " seekers, " << counts.boxes << " boxes (" << counts.elongated << " elongated), "
      << counts.ramps << " ramps: ";
  if (std::string(fail.object) == "rooms") {
    msg << "the random walls could not be split into " << fail.rooms << " rooms in " << kRoomFailures
        << " tries. Lower rooms.max.";
  } else {
    msg << fail.object << " " << fail.index << " (" << fail.kind << ", " << fail.cx << " x " << fail.cy
        << " cells, " << placement_region(fail.placement) << ") found no free spot in "
        << config.max_tries_per_object
        << " tries. Lower the counts (hiders, seekers, boxes, ramps) or raise max_tries_per_object.";
  }
  throw std::runtime_error(msg.str());
}

std::pair<double, double> food_respawn_spot(const SceneConfig& config, Rng& rng) {
  const Request req = food_request(config);
  const int c = footprint_cells(req.sx);
  const Cell cell = propose_cell(req.placement, c, c, req.anchor, 0, req.room, req.middle, rng);
  const double x = cell.i * kCellSize + rng.uniform(0.0, c * kCellSize - req.sx) + 0.5 * req.sx;
  const double y = cell.j * kCellSize + rng.uniform(0.0, c * kCellSize - req.sy) + 0.5 * req.sy;
  return {x, y};
}

double counting_box_x(int k, int step, int side) {
  const int start = kCountingStart + k * kCountingInterval;
  const double moved = std::clamp((step - start) * kCountingSpeed, 0.0, kCountingTravel);
  return kCountingAgentX + side * moved;
}

}  // namespace hns::physics
