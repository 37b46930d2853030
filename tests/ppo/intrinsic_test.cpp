// Count-based exploration (the paper's appendix "Intrinsic motivation"): bins, the random digit embeddings
// pooled per entity kind (checked digit by digit against the projection table), object invariance, the three
// state representations, 0.1 / √N, and a training run that logs the intrinsic return apart and resumes
// bit-identically with its counts.
#include "ppo/intrinsic.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "ppo/intrinsic_reward.hpp"
#include "ppo/trainer.hpp"
#include "ppo_test_util.hpp"

namespace hns::ppo {
namespace {

using physics::Spawn;

TEST(CountBased, BinsOverTheFixedRange) {
  EXPECT_EQ(CountHasher::bin(0.1f, 0.0f, 6.0f), 0);   // 0.5 of a bin
  EXPECT_EQ(CountHasher::bin(3.0f, 0.0f, 6.0f), 15);  // the middle
  EXPECT_EQ(CountHasher::bin(5.99f, 0.0f, 6.0f), 29);
  EXPECT_EQ(CountHasher::bin(7.0f, 0.0f, 6.0f), 29);  // above: the last bin
  EXPECT_EQ(CountHasher::bin(-1.0f, 0.0f, 6.0f), 0);  // below: the first
  EXPECT_EQ(CountHasher::bin(std::nanf(""), 0.0f, 6.0f), 0);
  EXPECT_EQ(CountHasher::bin(-0.5f, -1.0f, 1.0f), 7);  // 7.5 bins up
  EXPECT_THROW(parse_count_state("boxes"), physics::ConfigError);
}

// A batch of one empty-arena env with one agent and the given cubes.
struct Staged {
  batch::BatchSim sim;
  explicit Staged(int boxes) : sim(config(boxes)) {}
  static batch::BatchConfig config(int boxes) {
    batch::BatchConfig c;
    c.world = physics::WorldConfig::empty();
    c.world.scene.hiders = {1, 1};
    c.world.scene.seekers = {0, 0};
    c.world.scene.boxes = {boxes, boxes};
    c.world.scene.ramps = {0, 0};
    c.num_envs = 1;
    return c;
  }
  void load(Spawn agent, std::vector<Spawn> boxes) {
    physics::Scene s;
    s.num_hiders = 1;
    s.agents = {agent};
    s.boxes = std::move(boxes);
    sim.load_scene(0, s);
  }
};
Spawn agent_at(double x, double y) {
  return Spawn{x, y, physics::kAgentRadius, 0.3, 0.3, 0.3};
}
Spawn cube_at(double x, double y) {
  return Spawn{x, y, 0.25, 0.5, 0.5, 0.5};
}

TEST(CountBased, BoxPositionsArePooledEmbeddingsOfTheirBins) {
  Staged st(2);
  st.load(agent_at(5.0, 5.0), {cube_at(1.1, 3.05), cube_at(4.5, 0.7)});
  const CountHasher h(CountState::kBoxPos, 3);
  std::vector<uint8_t> d;
  h.digits(st.sim.state(), st.sim.layout(), 0, d);
  ASSERT_EQ(d.size(), 2u * kCountDigits);  // boxes only: x and y, 16 digits each
  // x: bins 5 (1.1 m) and 22 (4.5 m); y: bins 15 (3.05 m) and 3 (0.7 m); the digit-wise max of each pair.
  const int kBoxes = 2;
  for (int k = 0; k < kCountDigits; ++k) {
    EXPECT_EQ(d[k], std::max(h.embedding(kBoxes, 0, 5)[k], h.embedding(kBoxes, 0, 22)[k])) << k;
    EXPECT_EQ(d[kCountDigits + k], std::max(h.embedding(kBoxes, 1, 15)[k], h.embedding(kBoxes, 1, 3)[k]))
        << k;
    EXPECT_LE(d[k], 9);
  }
}

TEST(CountBased, ObjectInvariantAndEachRepresentationSeesItsOwnFeatures) {
  Staged st(2);
  const batch::BatchState& s = st.sim.state();
  const batch::Layout& L = st.sim.layout();
  const CountHasher pos(CountState::kBoxPos, 3), box(CountState::kBoxFull, 3), full(CountState::kFull, 3);
  st.load(agent_at(5.0, 5.0), {cube_at(1.1, 3.05), cube_at(4.5, 0.7)});
  const uint64_t p0 = pos.key(s, L, 0), b0 = box.key(s, L, 0), f0 = full.key(s, L, 0);
  // The same boxes in the other order: the same state for every representation (max-pooling).
  st.load(agent_at(5.0, 5.0), {cube_at(4.5, 0.7), cube_at(1.1, 3.05)});
  EXPECT_EQ(pos.key(s, L, 0), p0);
  EXPECT_EQ(box.key(s, L, 0), b0);
  EXPECT_EQ(full.key(s, L, 0), f0);
  // The agent elsewhere: only the full representation sees it.
  st.load(agent_at(2.0, 5.0), {cube_at(1.1, 3.05), cube_at(4.5, 0.7)});
  EXPECT_EQ(pos.key(s, L, 0), p0);
  EXPECT_EQ(box.key(s, L, 0), b0);
  EXPECT_NE(full.key(s, L, 0), f0);
  // A box turned by 90 degrees: box_full and full see its rotation, box_pos does not.
  st.load(agent_at(5.0, 5.0), {cube_at(1.1, 3.05), cube_at(4.5, 0.7)});
  st.sim.mutable_world(0).set_box_pose(0, 1.1, 3.05, 0.25, 1.5707963);
  st.sim.resync(0);
  EXPECT_EQ(pos.key(s, L, 0), p0);
  EXPECT_NE(box.key(s, L, 0), b0);
  // A box moved across a bin: every representation sees it.
  st.load(agent_at(5.0, 5.0), {cube_at(1.5, 3.05), cube_at(4.5, 0.7)});
  EXPECT_NE(pos.key(s, L, 0), p0);
  // Another projection seed: other digits.
  st.load(agent_at(5.0, 5.0), {cube_at(1.1, 3.05), cube_at(4.5, 0.7)});
  EXPECT_NE(CountHasher(CountState::kBoxPos, 4).key(s, L, 0), p0);
}

TEST(CountBased, RewardIsScaleOverRootCountPerEnv) {
  StateCounts c(2, 0.1);
  EXPECT_FLOAT_EQ(c.visit(0, 42), 0.1f);
  EXPECT_FLOAT_EQ(c.visit(0, 42), float(0.1 / std::sqrt(2.0)));
  EXPECT_FLOAT_EQ(c.visit(0, 42), float(0.1 / std::sqrt(3.0)));
  EXPECT_FLOAT_EQ(c.visit(1, 42), 0.1f);  // env 1 keeps its own counts
  EXPECT_FLOAT_EQ(c.visit(0, 7), 0.1f);
  EXPECT_EQ(c.distinct(0), 2);
  StateCounts back(2, 0.1);
  back.restore(c.sorted());
  EXPECT_EQ(back.sorted(), c.sorted());
  EXPECT_FLOAT_EQ(back.visit(0, 42), 0.05f);  // the fourth visit
}

using testing::metrics_but_timings;

TrainConfig count_config(const char* state = "full") {
  TrainConfig c = testing::tiny_intrinsic_config("count");
  c.count_state = state;
  return c;
}

TEST(CountBased, TrainingLogsTheIntrinsicReturnApartAndResumesWithItsCounts) {
  TrainConfig plain = count_config();
  plain.intrinsic = "none";
  Trainer without(plain);
  const IterationMetrics m0 = without.iterate();
  Trainer with(count_config());
  const IterationMetrics m1 = with.iterate();
  // Iteration 1 acts with the same seeded policy: the same episodes, the same game returns.
  EXPECT_EQ(m1.hider_reward, m0.hider_reward);
  EXPECT_EQ(m1.seeker_reward, m0.seeker_reward);
  EXPECT_EQ(m0.intrinsic_reward, 0.0);
  // Full-observation states are almost all new: about 0.1 per step for 20 steps.
  EXPECT_GT(m1.intrinsic_reward, 1.5);
  EXPECT_LE(m1.intrinsic_reward, 2.0 + 1e-6);
  EXPECT_NE(m1.to_json().find("\"intrinsic_reward\""), std::string::npos);

  // Resume: box positions repeat (boxes mostly stand still), so the second iteration's intrinsic return
  // depends on the counts of the first.
  Trainer boxes(count_config("box_pos"));
  const IterationMetrics b1 = boxes.iterate();
  EXPECT_LT(b1.intrinsic_reward, 1.0);  // far below one new state per step
  const std::string path = ::testing::TempDir() + "count_resume_" + std::to_string(::getpid()) + ".bin";
  boxes.save(path);
  const std::string second = metrics_but_timings(boxes.iterate());
  Trainer resumed(count_config("box_pos"));
  resumed.load(path);
  // (Without its counts the resumed run would take every state for new again and differ.)
  EXPECT_EQ(metrics_but_timings(resumed.iterate()), second);
  std::remove(path.c_str());
}

// A run without an intrinsic reward writes none of its keys (older versions read its files), and the config
// of a run or checkpoint from before the keys existed reads as having none, whatever the reading run uses.
TEST(CountBased, ConfigKeysStayOutOfRunsWithoutThem) {
  TrainConfig plain = count_config("box_pos");
  plain.intrinsic = "none";
  EXPECT_EQ(plain.to_json().find("intrinsic"), std::string::npos);
  EXPECT_EQ(plain.to_json().find("count_state"), std::string::npos);
  EXPECT_NE(count_config().to_json().find("\"intrinsic\": \"count\""), std::string::npos);
  TrainConfig reader = count_config();
  reader.init_heads = 0;
  reader.merge_run_json(plain.to_json(), "old config.json");
  EXPECT_EQ(reader.intrinsic, "none");
  EXPECT_EQ(reader.extrinsic_coef, 1.0);
  EXPECT_EQ(reader.init_heads, 1);
  TrainConfig back;
  back.merge_run_json(count_config().to_json(), "config.json");
  EXPECT_EQ(back.intrinsic, "count");
  EXPECT_EQ(back.count_state, "full");
  // What a run writes, read back, is the same run (a resume compares them): with init_* keys that do not
  // matter without init_from, and with intrinsic keys off their defaults while intrinsic is none.
  TrainConfig odd = plain;
  odd.init_heads = 0;
  odd.count_state = "full";
  TrainConfig read;
  read.merge_run_json(odd.to_json(), "config.json");
  EXPECT_EQ(odd.identity_mismatch(read), "");
  EXPECT_EQ(read.count_state, "full");
}

TEST(CountBased, BadKeysAreRefused) {
  TrainConfig c = count_config();
  c.intrinsic = "curiosity";
  EXPECT_THROW(c.validate(), physics::ConfigError);
  c = count_config();
  c.count_state = "boxes";
  EXPECT_THROW(c.validate(), physics::ConfigError);
  c = count_config();
  c.count_scale = -1;
  EXPECT_THROW(c.validate(), physics::ConfigError);
}

// The bonus is chosen once, by name, behind one interface: each kind says what it is and when it works, a
// name no kind answers to and a kind that keeps whole-run state under several ranks are refused.
TEST(IntrinsicReward, ChosenOnceByNameAndUnknownNamesRefused) {
  TrainConfig c = count_config();
  const nn::NetConfig net = nn::net_preset("small");
  c.intrinsic = "none";
  auto none = make_intrinsic_reward(c, net, 1);
  EXPECT_STREQ(none->name(), "none");
  EXPECT_FALSE(none->after_rollout_runs());
  c.intrinsic = "count";
  auto count = make_intrinsic_reward(c, net, 1);
  EXPECT_STREQ(count->name(), "count");
  EXPECT_FALSE(count->after_rollout_runs());
  c.intrinsic = "rnd";
  auto rnd = make_intrinsic_reward(c, net, 1);
  EXPECT_STREQ(rnd->name(), "rnd");
  EXPECT_TRUE(rnd->after_rollout_runs());
  for (const char* kind : {"count", "rnd"}) {
    c.intrinsic = kind;
    EXPECT_THROW(make_intrinsic_reward(c, net, 2), physics::ConfigError) << kind;
  }
  c.intrinsic = "curiosity";  // past validate(), the factory still has no default
  EXPECT_THROW(make_intrinsic_reward(c, net, 1), physics::ConfigError);
  // A checkpoint of a run whose bonus this build does not know is refused, not read as another kind's.
  CheckpointReader r("", 0, "x");
  try {
    read_intrinsic_state(r, c, net);
    FAIL() << "an unknown kind's section was read";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("curiosity"), std::string::npos) << e.what();
  }
}

// Each kind writes its own checkpoint section and reads it back into the same state: the counts per env, the
// RND predictor and its optimiser (bytes written again after a restore equal the first, and the restored
// reward comes from another seed, so a restore that skipped anything would write other bytes).
TEST(IntrinsicReward, EachKindRoundTripsItsCheckpointSection) {
  TrainConfig c = count_config();
  nn::NetConfig net = nn::net_preset("small");
  const Trainer t(c);
  net.obs = t.net().config().obs;
  const batch::BatchState& s = t.sim().state();
  for (const char* kind : {"none", "count", "rnd"}) {
    c.intrinsic = kind;
    auto a = make_intrinsic_reward(c, net, 1);
    for (int e = 0; e < c.envs; ++e) a->step_bonus(s, t.sim().layout(), e, e);
    CheckpointWriter w;
    a->save(w);
    const std::string bytes = w.bytes();
    CheckpointReader r(bytes.data(), bytes.size(), "section");
    const auto st = read_intrinsic_state(r, c, net);
    EXPECT_TRUE(r.at_end()) << kind;
    st->check([](const std::string& why) { throw std::runtime_error(why); });
    TrainConfig other = c;
    other.seed = c.seed + 1;
    auto b = make_intrinsic_reward(other, net, 1);
    b->restore(*st);
    CheckpointWriter again;
    b->save(again);
    EXPECT_TRUE(again.bytes() == bytes) << kind << ": the restored state writes other bytes";
    if (std::string(kind) != "none") {
      EXPECT_FALSE(bytes.empty()) << kind;
    }
  }
}

}  // namespace
}  // namespace hns::ppo
