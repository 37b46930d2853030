// Episode recording: frames are exactly the game's states (the auto-reset loses nothing), the preparation
// phase and rewards line up, and recordings are deterministic whatever the thread or env count.
#include "replay/recorder.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "batch/scenes.hpp"

namespace hns::replay {
namespace {

namespace phys = hns::physics;

RecordConfig config_for(const std::string& scene, int episodes, int envs, uint64_t seed, int threads = 1) {
  RecordConfig c;
  c.scene = scene;
  c.episodes = episodes;
  c.game = batch::scene_config(scene);
  c.game.num_envs = envs;
  c.game.seed = seed;
  c.game.threads = threads;
  return c;
}

std::vector<TrajectoryEpisode> record(const RecordConfig& c) {
  std::vector<TrajectoryEpisode> out;
  RandomActions actions(c.game.seed);
  const RecordSummary s =
      record_episodes(c, actions, [&](const TrajectoryEpisode& ep) { out.push_back(ep); });
  EXPECT_EQ(s.recorded, c.episodes);
  EXPECT_EQ(int(out.size()), c.episodes);
  return out;
}

TEST(Recorder, RecordingConfigKeepsThePreparationPhase) {
  for (const char* name : {"quadrant", "full", "empty"}) {
    const batch::BatchConfig game = batch::scene_config(name);
    const batch::BatchConfig rec = recording_batch_config(game);
    EXPECT_EQ(rec.world.horizon, game.world.horizon + 1) << name;
    EXPECT_EQ(rec.world.prep_steps(), game.world.prep_steps()) << name;
  }
  batch::BatchConfig game;
  game.world.horizon = 7;
  for (double fraction : {0.0, 0.1, 0.5, 0.9}) {
    game.world.prep_fraction = fraction;
    EXPECT_EQ(recording_batch_config(game).world.prep_steps(), game.world.prep_steps()) << fraction;
  }
}

// Frames 0..horizon-1 and every reward equal what a plain batch (the game's own horizon) shows after each
// step.
TEST(Recorder, FramesMatchThePlainGameStepForStep) {
  const RecordConfig c = config_for("quadrant", 1, 1, 5);
  const TrajectoryEpisode ep = record(c).at(0);
  const int horizon = c.game.world.horizon;
  ASSERT_EQ(ep.frames, horizon + 1);
  ASSERT_EQ(ep.horizon, horizon);
  ASSERT_EQ(ep.prep_steps, 32);

  batch::BatchSim sim(c.game);
  RandomActions actions(c.game.seed);
  std::vector<phys::AgentAction> step_actions(size_t(sim.layout().max_agents));
  const int a_n = ep.num_agents(), ma = sim.layout().max_agents;
  ASSERT_EQ(a_n, sim.world(0).num_agents());
  ASSERT_EQ(ep.num_boxes, sim.world(0).num_boxes());
  ASSERT_EQ(int(ep.walls.size()), int(sim.world(0).scene().wall_boxes.size()));
  for (int t = 0; t <= horizon; ++t) {
    if (t > 0) {
      actions(sim, step_actions);
      sim.step(step_actions);
      for (int a = 0; a < a_n; ++a) {
        EXPECT_EQ(ep.action[(size_t(t) * a_n + a) * 5 + 0], step_actions[a].move_x);
        EXPECT_EQ(ep.action[(size_t(t) * a_n + a) * 5 + 3], step_actions[a].grab);
        EXPECT_EQ(ep.reward[size_t(t) * a_n + a], sim.state().reward[a]) << "t " << t;
      }
    }
    EXPECT_EQ(ep.prep[t], t <= 32 ? 1 : 0);
    if (t == horizon) {
      EXPECT_EQ(sim.state().done[0], 1);  // the plain batch has already moved on to its next episode
      break;
    }
    const phys::World& w = sim.world(0);
    for (int a = 0; a < a_n; ++a) {
      const phys::BodyState s = w.agent_state(a);
      EXPECT_EQ(ep.agent_pose[(size_t(t) * a_n + a) * 4 + 0], float(s.pos[0])) << "t " << t;
      EXPECT_EQ(ep.agent_pose[(size_t(t) * a_n + a) * 4 + 1], float(s.pos[1])) << "t " << t;
      EXPECT_EQ(ep.agent_pose[(size_t(t) * a_n + a) * 4 + 3], float(s.yaw())) << "t " << t;
      EXPECT_EQ(ep.agent_holding[size_t(t) * a_n + a], w.agent_holding(a));
      for (int j = 0; j < a_n; ++j) {
        EXPECT_EQ(ep.vis_agents[(size_t(t) * a_n + a) * a_n + j], sim.state().vis_agents[a * ma + j]);
      }
      for (int k = 0; k < kTrajectoryLidarRays; ++k) {
        const double d = sim.state().lidar[a * batch::Layout::kLidar + k];
        EXPECT_NEAR(ep.lidar[(size_t(t) * a_n + a) * kTrajectoryLidarRays + k] * kLidarUnit, d,
                    0.51 * kLidarUnit);
      }
    }
    for (int b = 0; b < ep.num_boxes; ++b) {
      EXPECT_EQ(ep.box_pose[(size_t(t) * ep.num_boxes + b) * 4 + 0], float(w.box_state(b).pos[0]));
      const uint8_t lock = ep.object_lock[size_t(t) * ep.num_objects() + b];
      EXPECT_EQ(lock != kUnlocked, w.object_locked(b));
      if (lock != kUnlocked) {
        EXPECT_EQ(lock, w.object_lock_team(b) == 0 ? kLockedByHiders : kLockedBySeekers);
      }
    }
  }
  // Rewards are zero in the preparation phase and +-1 (or -10 out of bounds) after it; the return adds them
  // up.
  double hider_return = 0;
  for (int t = 0; t <= horizon; ++t) {
    for (int a = 0; a < a_n; ++a) {
      const float r = ep.reward[size_t(t) * a_n + a];
      if (t <= 32) {
        EXPECT_EQ(r, 0.0f);
      } else {
        EXPECT_TRUE(r == 1.0f || r == -1.0f || r == -10.0f) << r;
      }
    }
    hider_return += (ep.reward[size_t(t) * a_n] + ep.reward[size_t(t) * a_n + 1]) / 2;
  }
  EXPECT_DOUBLE_EQ(ep.hider_return, hider_return);
}

TEST(Recorder, EveryPresetRecordsAndRoundTrips) {
  for (const char* name : {"quadrant", "full", "empty"}) {
    const RecordConfig c = config_for(name, 2, 2, 3);
    TrajectoryFile file;
    file.episodes = record(c);
    for (const TrajectoryEpisode& ep : file.episodes) {
      EXPECT_EQ(ep.scene, name);
      EXPECT_EQ(ep.frames, c.game.world.horizon + 1);
      EXPECT_EQ(int(ep.box_sizes.size()), ep.num_boxes);
    }
    EXPECT_EQ(file.episodes[0].env, 0);
    EXPECT_EQ(file.episodes[1].env, 1);
    EXPECT_EQ(decode_trajectory(encode_trajectory(file)), file) << name;
  }
}

TEST(Recorder, DeterministicAcrossThreadsAndEnvCounts) {
  auto bytes = [](const std::vector<TrajectoryEpisode>& eps) {
    TrajectoryFile f;
    f.episodes = eps;
    return encode_trajectory(f);
  };
  const std::vector<TrajectoryEpisode> one = record(config_for("quadrant", 4, 2, 9, 1));
  EXPECT_EQ(bytes(one), bytes(record(config_for("quadrant", 4, 2, 9, 2))));
  // Env 0's first episode depends only on (seed, env, episode), not on how many envs ran beside it.
  const std::vector<TrajectoryEpisode> alone = record(config_for("quadrant", 1, 1, 9));
  EXPECT_EQ(alone[0], one[0]);
  // Each env records consecutive episodes.
  EXPECT_EQ(one[2].env, 0);
  EXPECT_EQ(one[2].episode, 1);
  EXPECT_EQ(one[3].env, 1);
  EXPECT_EQ(one[3].episode, 1);
  EXPECT_NE(one[0].agent_pose, one[2].agent_pose);
}

TEST(Recorder, RejectsZeroEpisodes) {
  RandomActions actions(1);
  EXPECT_THROW(record_episodes(config_for("quadrant", 0, 1, 1), actions, [](const TrajectoryEpisode&) {}),
               phys::ConfigError);
}

}  // namespace
}  // namespace hns::replay
