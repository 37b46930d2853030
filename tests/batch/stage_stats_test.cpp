// The stage detectors (docs/training.md "Stages"): their geometry on hand-made footprints, and the episode
// statistics BatchSim reports on staged episodes (a fort with both doors sealed, a seeker looking over a wall
// from a box) and under a random policy (no fort, on average).
#include "batch/stage_stats.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <memory>
#include <vector>

#include "batch/batch_sim.hpp"
#include "physics/rng.hpp"

namespace hns::batch {
namespace {

using physics::Scene;
using physics::Spawn;

constexpr double kPi = 3.14159265358979323846;

Footprint square(float x, float y, float half, float yaw = 0.0f) {
  return Footprint{x, y, std::cos(yaw), std::sin(yaw), half, half};
}

TEST(StageGeometry, FootprintDistance) {
  EXPECT_NEAR(footprint_distance(square(1, 1, 0.25f), square(2.5f, 1, 0.25f)), 1.0f, 1e-6);
  EXPECT_NEAR(footprint_distance(square(1, 1, 0.25f), square(2, 2, 0.25f)), std::sqrt(0.5f), 1e-6)
      << "corner to corner";
  EXPECT_EQ(footprint_distance(square(1, 1, 0.25f), square(1.3f, 1.1f, 0.25f)), 0.0f) << "overlapping";
  // A square turned 45 degrees points a corner (0.25 * sqrt 2 from its centre) at a wall face.
  const Footprint wall{3.1f, 3.0f, 1, 0, 0.05f, 2.0f};
  EXPECT_NEAR(footprint_distance(square(2.5f, 3.0f, 0.25f, float(kPi / 4)), wall),
              3.05f - 2.5f - 0.25f * std::sqrt(2.0f), 1e-5);
}

TEST(StageGeometry, StandsOnTheTopOfABoxOnly) {
  const Footprint box = square(2, 2, 0.25f);
  EXPECT_TRUE(stands_on(box, 0.5f, 2.1f, 1.9f, 0.65f));
  EXPECT_FALSE(stands_on(box, 0.5f, 2.1f, 1.9f, 0.15f)) << "on the floor beside it";
  EXPECT_FALSE(stands_on(box, 0.5f, 2.4f, 1.9f, 0.65f)) << "beside its footprint";
}

// A hider is screened by a box when less than an agent's diameter (0.3 m) is left between its body (radius
// 0.15 m) and the box's footprint, measured from any side, corners included.
TEST(StageGeometry, AHiderBesideABoxIsScreenedAnAgentsWidthAwayIsNot) {
  const Footprint box[] = {square(2, 2, 0.25f)};
  const float touching = 2.0f + 0.25f + 0.15f, floor = 0.15f;  // the hider's centre on the floor
  EXPECT_FALSE(hider_screened({}, touching, 2.0f, floor)) << "no locked box";
  EXPECT_TRUE(hider_screened(box, touching, 2.0f, floor)) << "touching its face";
  EXPECT_TRUE(hider_screened(box, touching + 0.29f, 2.0f, floor)) << "0.29 m between them: no agent fits";
  EXPECT_FALSE(hider_screened(box, touching + 0.31f, 2.0f, floor)) << "0.31 m: a seeker fits between";
  EXPECT_TRUE(hider_screened(box, 2.0f, 2.0f - 0.25f - 0.15f - 0.29f, floor)) << "on the other axis";
  // Off a corner: the gap is the distance to the corner (2.25, 2.25), less the hider's radius.
  const float diag = 0.44f / std::sqrt(2.0f);
  EXPECT_TRUE(hider_screened(box, 2.25f + diag, 2.25f + diag, floor));
  EXPECT_FALSE(hider_screened(box, 2.25f + 0.34f, 2.25f + 0.34f, floor)) << "0.48 m from the corner";
  const Footprint turned[] = {square(2, 2, 0.25f, float(kPi / 4))};
  EXPECT_TRUE(hider_screened(turned, 2.0f + 0.25f * std::sqrt(2.0f) + 0.44f, 2.0f, floor))
      << "a turned cube's corner";
  EXPECT_FALSE(hider_screened(box, 2.0f, 2.0f, 0.65f)) << "standing on top of the box: in plain view";
  EXPECT_FALSE(hider_screened(box, touching, 2.0f, 0.65f)) << "standing on something beside it";
}

// A door in a wall along y at x = 3.1, open over y in [1.0, 1.7] (2 cells plus the wall pieces' ends).
DoorGap test_gap() {
  DoorGap g;
  g.axis = 1;
  g.line = 3.1f;
  g.half_thickness = 0.05f;
  g.lo = 1.0f;
  g.hi = 1.7f;
  return g;
}

TEST(StageGeometry, ACubeAgainstTheDoorSealsIt) {
  const DoorGap g = test_gap();
  const float inside = 3.1f + 0.05f + 0.25f + 0.02f, outside = 3.1f - 0.05f - 0.25f - 0.02f;
  EXPECT_FALSE(door_sealed(g, {})) << "an empty door is open";
  const Footprint centred[] = {square(inside, 1.35f, 0.25f)};
  EXPECT_TRUE(door_sealed(g, centred)) << "0.1 m left on either side: no agent (0.3 m) passes";
  const Footprint outer[] = {square(outside, 1.35f, 0.25f)};
  EXPECT_TRUE(door_sealed(g, outer)) << "from the other side as well";
  const Footprint in_opening[] = {square(3.1f, 1.35f, 0.25f)};
  EXPECT_TRUE(door_sealed(g, in_opening));
  const Footprint shifted[] = {square(inside, 1.65f, 0.25f)};
  EXPECT_FALSE(door_sealed(g, shifted)) << "0.4 m of the opening left free";
  const Footprint away[] = {square(inside + 0.32f, 1.35f, 0.25f)};
  EXPECT_FALSE(door_sealed(g, away)) << "an agent fits between the box and the wall";
  const Footprint turned[] = {square(inside + 0.1f, 1.35f, 0.25f, float(kPi / 4))};
  EXPECT_TRUE(door_sealed(g, turned)) << "a turned cube's corner covers the opening too";
}

TEST(StageGeometry, BoxesSealFromOneSideNotHalfFromEach) {
  DoorGap g = test_gap();
  g.hi = 2.2f;  // a 1.2 m opening
  const float inside = 3.42f, outside = 2.78f;
  const Footprint both_inside[] = {square(inside, 1.15f, 0.25f), square(inside, 1.85f, 0.25f)};
  EXPECT_TRUE(door_sealed(g, both_inside)) << "gaps of 0.2 and 0.1 m";
  EXPECT_FALSE(door_sealed(g, std::span<const Footprint>(both_inside, 1))) << "one cube leaves 0.55 m";
  // One cube on each side: each side alone leaves a passable stretch; an agent weaves through.
  const Footprint split[] = {square(inside, 1.15f, 0.25f), square(outside, 1.85f, 0.25f)};
  EXPECT_FALSE(door_sealed(g, split));
}

// Every door of generated quadrant scenes lies on its wall's line (3.1 m) and opens between the wall pieces:
// 0.7 m for two cells, 0.6 m where the one-cell piece at the wall's end was dropped (the opening then runs to
// the next wall's face), 0.9 m each where both doors dropped the room's corner piece (the corner is open).
TEST(StageGeometry, QuadrantDoorGapsMatchTheWallPieces) {
  physics::SceneConfig config = physics::SceneConfig::quadrant();
  config.p_door_dropout = 0.0;
  physics::Scene scene;
  std::map<int, int> widths;  // cm -> doors
  for (uint64_t episode = 0; episode < 2000; ++episode) {
    physics::Rng rng(1, 0, episode);
    physics::generate_scene(config, rng, scene);
    ASSERT_EQ(scene.doors.size(), 2u);
    for (const physics::DoorCells& d : scene.doors) {
      const DoorGap g = door_gap(scene, d);
      EXPECT_NEAR(g.line, 3.1f, 1e-6);
      const int cm = int(std::lround((g.hi - g.lo) * 100));
      ++widths[cm];
      EXPECT_TRUE(cm == 60 || cm == 70 || cm == 90)
          << "episode " << episode << ": " << g.lo << " .. " << g.hi;
    }
  }
  EXPECT_GT(widths[70], 3000);
  EXPECT_GT(widths[60], 50) << "doors at the walls' ends";
  EXPECT_GT(widths[90], 0) << "the open corner";
}

// The quadrant game with both doors (no dropout) and its horizon and preparation phase.
BatchConfig quadrant_config(int envs) {
  BatchConfig c;
  c.world = physics::WorldConfig::quadrant();
  c.world.scene.p_door_dropout = 0.0;
  c.num_envs = envs;
  return c;
}

// Stages a fort: takes the env's quadrant scene, puts a cube against each door inside the room with a
// hider behind it facing it, both seekers outside in the far corner and the ramp at `ramp`. Returns the
// scene's door gaps.
std::vector<DoorGap> stage_fort(BatchSim& sim, double ramp_x, double ramp_y) {
  // An episode whose doors are clear of the room's corners, so cubes and hiders fit in front of them.
  physics::World& world = sim.mutable_world(0);
  Scene scene;
  std::vector<DoorGap> gaps;
  for (uint64_t episode = 0;; ++episode) {
    world.reset(episode);
    scene = world.scene();
    gaps.clear();
    // Cubes and hiders must fit inside the room in front of each door and miss each other.
    float along_y = -1, along_x = -1;  // door centres on the vertical and on the horizontal room wall
    for (const physics::DoorCells& d : scene.doors) {
      gaps.push_back(door_gap(scene, d));
      (gaps.back().axis == 1 ? along_y : along_x) = 0.5f * (gaps.back().lo + gaps.back().hi);
    }
    const bool clear = scene.doors.size() == 2 && along_y > 0.6f && along_y < 2.5f && along_x > 3.7f &&
                       along_x < 5.3f && (along_y < 2.0f || along_x > 4.3f);
    if (clear) break;
    EXPECT_LT(episode, 200u) << "no quadrant scene with two doors clear of the corners";
    if (episode >= 200) return {};
  }
  scene.agents.clear();
  scene.boxes.clear();
  std::vector<double> yaws;
  for (const DoorGap& g : gaps) {
    const double mid = 0.5 * (g.lo + g.hi);
    // Inside the room: +x of the vertical wall, -y of the horizontal one.
    const double box = g.axis == 1 ? g.line + 0.05 + 0.25 + 0.03 : g.line - 0.05 - 0.25 - 0.03;
    const double agent = g.axis == 1 ? box + 0.25 + 0.15 + 0.05 : box - 0.25 - 0.15 - 0.05;
    scene.boxes.push_back(g.axis == 1 ? Spawn{box, mid, 0.25, 0.5, 0.5, 0.5}
                                      : Spawn{mid, box, 0.25, 0.5, 0.5, 0.5});
    scene.agents.push_back(g.axis == 1 ? Spawn{agent, mid, 0.15, 0.3, 0.3, 0.3}
                                       : Spawn{mid, agent, 0.15, 0.3, 0.3, 0.3});
    yaws.push_back(g.axis == 1 ? -kPi / 2 : kPi);  // face -x (the vertical wall's box), +y (the other's)
  }
  scene.agents.push_back(Spawn{0.8, 5.2, 0.15, 0.3, 0.3, 0.3});
  scene.agents.push_back(Spawn{1.4, 5.2, 0.15, 0.3, 0.3, 0.3});
  scene.num_hiders = scene.num_seekers = 2;
  scene.ramps = {Spawn{ramp_x, ramp_y, 0.25, 0.5, 0.5, 0.5}};
  sim.load_scene(0, scene);
  for (int h = 0; h < 2; ++h) {
    const Spawn& a = scene.agents[size_t(h)];
    sim.mutable_world(0).set_agent_pose(h, a.x, a.y, a.z, yaws[size_t(h)]);
  }
  sim.resync(0);
  return gaps;
}

// Plays env 0 to the end of its episode; the agents in `lockers` hold lock down throughout (the lock team
// unlocks a box it sees in range without pressing lock, docs/game.md §3.4).
EpisodeStats play_episode(BatchSim& sim, std::vector<int> lockers) {
  std::vector<AgentAction> acts(size_t(sim.layout().max_agents));
  for (int h : lockers) acts[size_t(h)].lock = 1;
  for (int t = 0; t < 1000; ++t) {
    sim.step(acts);
    if (!sim.finished().empty()) return sim.finished()[0];
  }
  ADD_FAILURE() << "the episode did not end";
  return {};
}

TEST(StageDetectors, StagedFortWithBothDoorsSealedCountsTwo) {
  BatchSim sim(quadrant_config(1));
  ASSERT_EQ(stage_fort(sim, 5.2, 0.8).size(), 2u);
  const EpisodeStats st = play_episode(sim, {0, 1});
  EXPECT_EQ(st.num_box_lock_prep, 2.0f);
  EXPECT_EQ(st.num_doors, 2.0f);
  EXPECT_EQ(st.num_door_sealed_prep, 2.0f);
  EXPECT_EQ(st.num_door_sealed, 2.0f);
  EXPECT_EQ(st.ramp_in_room_prep, 1.0f) << "the ramp stands in the room";
  EXPECT_EQ(st.num_door_blocked_prep, 2.0f) << "a sealed door is blocked too";
  EXPECT_EQ(st.hiders_in_room_prep, 1.0f) << "both hiders stay behind their cubes";
  EXPECT_EQ(st.hiders_screened_prep, 1.0f) << "each beside its locked cube";
  EXPECT_EQ(st.hider_seen_frac, 0.0f) << "nobody sees into a sealed room from the floor";
  EXPECT_EQ(st.seeker_high_seen, 0.0f);
  EXPECT_EQ(st.seeker_high, 0.0f) << "the seekers stay on the floor";
  EXPECT_EQ(st.box_surf, 0.0f);
}

TEST(StageDetectors, OneLockedCubeSealsOneDoorAndAnUnlockedOneNone) {
  BatchSim sim(quadrant_config(1));
  ASSERT_EQ(stage_fort(sim, 1.0, 1.0).size(), 2u);
  EpisodeStats st = play_episode(sim, {1});
  EXPECT_EQ(st.num_box_lock_prep, 1.0f);
  EXPECT_EQ(st.num_door_sealed_prep, 1.0f);
  EXPECT_EQ(st.ramp_in_room_prep, 0.0f) << "the ramp is outside the room";
  EXPECT_EQ(st.hiders_screened_prep, 0.5f) << "one of the two hiders is beside a locked cube";
  ASSERT_EQ(stage_fort(sim, 1.0, 1.0).size(), 2u);
  st = play_episode(sim, {});
  EXPECT_EQ(st.num_door_sealed_prep, 0.0f) << "cubes in place but unlocked seal nothing";
  EXPECT_EQ(st.num_door_blocked_prep, 2.0f) << "but they block both doors";
  EXPECT_EQ(st.hiders_in_room_prep, 1.0f);
  EXPECT_EQ(st.hiders_screened_prep, 0.0f) << "an unlocked cube screens nobody";
}

// The shelter the campaign's hiders learned (docs/training.md "The campaign so far"): both hiders in the
// room's far corner (x 5.85, y 0.15), each facing a cube in front of it, both doors open. Locked, the cubes
// screen both hiders though no door is sealed or blocked; unlocked, they screen nobody.
TEST(StageDetectors, HidersBesideLockedCubesInTheRoomsCornerAreScreened) {
  for (const bool lock : {true, false}) {
    BatchSim sim(quadrant_config(1));
    physics::World& world = sim.mutable_world(0);
    world.reset(0);
    Scene scene = world.scene();
    scene.agents = {Spawn{5.55, 0.45, 0.15, 0.3, 0.3, 0.3}, Spawn{5.0, 0.45, 0.15, 0.3, 0.3, 0.3},
                    Spawn{0.8, 5.2, 0.15, 0.3, 0.3, 0.3}, Spawn{1.4, 5.2, 0.15, 0.3, 0.3, 0.3}};
    scene.num_hiders = scene.num_seekers = 2;
    // Cubes 0.05 m in front of the hiders (along +y), 0.05 m apart: no agent passes between them.
    scene.boxes = {Spawn{5.55, 0.9, 0.25, 0.5, 0.5, 0.5}, Spawn{5.0, 0.9, 0.25, 0.5, 0.5, 0.5}};
    scene.ramps = {Spawn{1.0, 1.0, 0.25, 0.5, 0.5, 0.5}};
    sim.load_scene(0, scene);
    for (int h = 0; h < 2; ++h) {
      const Spawn& a = scene.agents[size_t(h)];
      world.set_agent_pose(h, a.x, a.y, a.z, kPi);  // facing +y, its cube
    }
    sim.resync(0);
    const EpisodeStats st = play_episode(sim, lock ? std::vector<int>{0, 1} : std::vector<int>{});
    EXPECT_EQ(st.num_box_lock_prep, lock ? 2.0f : 0.0f);
    EXPECT_EQ(st.hiders_in_room_prep, 1.0f);
    EXPECT_EQ(st.hiders_screened_prep, lock ? 1.0f : 0.0f) << "locked: " << lock;
    EXPECT_EQ(st.num_door_sealed_prep, 0.0f) << "the doors stay open";
    EXPECT_EQ(st.num_door_blocked_prep, 0.0f);
  }
}

// One hider, one seeker, up to one box and one ramp, no walls and no preparation phase.
BatchConfig one_on_one(int horizon) {
  BatchConfig c;
  c.world = physics::WorldConfig::empty();
  c.world.prep_fraction = 0.0;
  c.world.horizon = horizon;
  c.rules.penalize_objects_out = false;
  c.world.scene.boxes = c.world.scene.ramps = {0, 1};
  c.world.scene.hiders = c.world.scene.seekers = {1, 1};
  c.num_envs = 1;
  return c;
}

// A seeker on a cube behind a 0.5 m wall sees the hider beyond it: it stood higher than a wall while a
// hider was seen. Turned away from the hider it still stood high (seeker_high) but saw nobody from there.
// From the floor it sees nothing and stands high nowhere.
TEST(StageDetectors, SeekerOnABoxSeeingOverAWall) {
  BatchSim sim(one_on_one(4));
  Scene scene;
  scene.num_hiders = scene.num_seekers = 1;
  scene.wall_boxes = {physics::StaticBox{3.0, 3.2, 0.25, 1.0, 0.05, 0.25}};
  scene.agents = {Spawn{3.0, 1.5, 0.15, 0.3, 0.3, 0.3}, Spawn{3.0, 3.5, 0.65, 0.3, 0.3, 0.3}};
  scene.boxes = {Spawn{3.0, 3.5, 0.25, 0.5, 0.5, 0.5}};
  sim.load_scene(0, scene);
  EpisodeStats st = play_episode(sim, {});
  EXPECT_EQ(st.seeker_high_seen, 1.0f);
  EXPECT_EQ(st.seeker_high, 1.0f);
  EXPECT_EQ(st.hider_seen_frac, 1.0f);
  EXPECT_NEAR(st.ramp_wall_dist, 6.0f, 1e-6) << "no ramp: nothing came near a wall";
  sim.load_scene(0, scene);
  sim.mutable_world(0).set_agent_pose(1, 3.0, 3.5, 0.65, kPi);  // on the cube, its back to the wall
  sim.resync(0);
  st = play_episode(sim, {});
  EXPECT_EQ(st.hider_seen_frac, 0.0f) << "the hider is behind the seeker";
  EXPECT_EQ(st.seeker_high_seen, 0.0f);
  EXPECT_EQ(st.seeker_high, 1.0f) << "it stood on the cube all the same";
  scene.agents[1].z = 0.15;
  scene.boxes.clear();
  scene.ramps = {Spawn{3.0, 4.0, 0.25, 0.5, 0.5, 0.5}};
  sim.load_scene(0, scene);
  st = play_episode(sim, {});
  EXPECT_EQ(st.seeker_high_seen, 0.0f);
  EXPECT_EQ(st.seeker_high, 0.0f);
  EXPECT_EQ(st.hider_seen_frac, 0.0f);
  EXPECT_NEAR(st.ramp_wall_dist, 4.0 - 0.25 - 3.25, 0.02) << "the ramp's near edge to the wall's face";
}

// A seeker running at a hider approaches it at about its running speed; running away, at minus that.
TEST(StageDetectors, SeekerApproachIsItsSpeedTowardsTheNearestHider) {
  for (int dir : {+1, -1}) {
    BatchSim sim(one_on_one(6));
    Scene scene;
    scene.num_hiders = scene.num_seekers = 1;
    scene.agents = {Spawn{5.0, 3.0, 0.15, 0.3, 0.3, 0.3}, Spawn{2.5, 3.0, 0.15, 0.3, 0.3, 0.3}};
    sim.load_scene(0, scene);
    std::vector<AgentAction> acts(size_t(sim.layout().max_agents));
    acts[1].move_x = dir > 0 ? 10 : 0;  // the seeker runs along +x (towards the hider) or -x
    EpisodeStats st;
    for (int t = 0; t < 6; ++t) sim.step(acts);
    ASSERT_EQ(sim.finished().size(), 1u);
    st = sim.finished()[0];
    EXPECT_GT(dir * st.seeker_approach, 3.0f) << "dir " << dir;
  }
}

// A seeker standing on a cube that a hider pushes along rides it: from the third such step on, the episode
// counts as box surfing.
TEST(StageDetectors, SeekerRidingAPushedBoxSurfsFromTheThirdStep) {
  Scene scene;
  scene.num_hiders = scene.num_seekers = 1;
  scene.agents = {Spawn{2.0, 3.0, 0.15, 0.3, 0.3, 0.3}, Spawn{2.45, 3.0, 0.65, 0.3, 0.3, 0.3}};
  scene.boxes = {Spawn{2.45, 3.0, 0.25, 0.5, 0.5, 0.5}};
  // Surfing steps in the first `steps` steps of an episode long enough to go on; and the box_surf flag of an
  // episode of exactly `steps` steps (the physics is the same up to its end).
  auto play = [&](int horizon, int steps) {
    auto sim = std::make_unique<BatchSim>(one_on_one(horizon));
    sim->load_scene(0, scene);
    std::vector<AgentAction> acts(size_t(sim->layout().max_agents));
    acts[0].move_x = 8;  // the hider pushes at 0.54 of full force; faster throws the rider off
    for (int t = 0; t < steps; ++t) sim->step(acts);
    return sim;
  };
  auto surf_steps = [&](int steps) { return play(steps + 5, steps)->state().stat_run[kSurfCount]; };
  auto flag = [&](int steps) {
    const auto sim = play(steps, steps);
    return sim->finished().size() == 1 ? sim->finished()[0].box_surf : -1.0f;
  };
  ASSERT_GE(surf_steps(12), 5.0f) << "the seeker rides the pushed cube";
  EXPECT_EQ(flag(12), 1.0f);
  // The shortest episode with kSurfSteps (3) surfing steps counts; one step shorter does not.
  int h = 1;
  while (surf_steps(h) < float(kSurfSteps)) ++h;
  EXPECT_EQ(surf_steps(h - 1), float(kSurfSteps - 1));
  EXPECT_EQ(flag(h), 1.0f) << h << " steps";
  EXPECT_EQ(flag(h - 1), 0.0f) << h - 1 << " steps";
}

// A random policy locks boxes wherever they happen to be: that seals a door hardly ever, and no seeker rides
// a box. (The detectors must not fire on play without intent.)
TEST(StageDetectors, RandomPolicyCountsNoFortOnAverage) {
  BatchConfig config = quadrant_config(16);
  config.threads = 2;
  BatchSim sim(config);
  const int A = sim.layout().max_agents;
  std::vector<AgentAction> acts(size_t(config.num_envs) * A);
  physics::Rng rng(7, 0, 0);
  double episodes = 0, sealed = 0, blocked = 0, locked = 0, surf = 0, approach = 0, screened = 0;
  for (int t = 0; t < 3 * 80; ++t) {
    for (AgentAction& a : acts) a = physics::random_action(rng);
    sim.step(acts);
    for (const EpisodeStats& st : sim.finished()) {
      episodes += 1;
      sealed += st.num_door_sealed_prep;
      blocked += st.num_door_blocked_prep;
      locked += st.num_box_lock_prep;
      surf += st.box_surf;
      approach += st.seeker_approach;
      screened += st.hiders_screened_prep;
    }
  }
  ASSERT_EQ(episodes, 48.0);
  EXPECT_GT(locked, 0.0) << "random play does lock boxes";
  EXPECT_LT(sealed / episodes, 0.1) << "but seals doors hardly ever";
  EXPECT_LT(blocked / episodes, 0.2) << "and blocks them seldom";
  EXPECT_LE(sealed, blocked) << "a sealed door is a blocked one";
  EXPECT_EQ(surf, 0.0);
  EXPECT_LT(std::abs(approach / episodes), 0.3) << "random seekers do not chase";
  EXPECT_LT(screened / episodes, 0.05) << "random hiders end prep beside a locked box seldom: " << screened;
}

}  // namespace
}  // namespace hns::batch
