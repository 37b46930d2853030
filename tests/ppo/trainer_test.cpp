// The PPO trainer: config validation, determinism across thread counts, bit-identical resume, the NaN stop,
// and the value-target normaliser. Refused checkpoints, exported policies and runs started from another
// run's checkpoint are in trainer_checkpoint_test.cpp.
#include "ppo/trainer.hpp"
#include "ppo/atomic_file.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "nn/precision.hpp"
#include "physics/scene.hpp"
#include "ppo/batch_obs.hpp"
#include "ppo/policy.hpp"
#include "ppo_test_util.hpp"

namespace hns::ppo {
namespace {

using testing::metrics_but_timings;
using testing::params_of;
using testing::temp_path;
using testing::tiny_quadrant;

// Everything of an iteration's metrics that does not depend on wall time.
std::string results_of(const IterationMetrics& m) {
  char buf[512];
  std::snprintf(buf, sizeof buf, "%lld %lld %d %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g",
                static_cast<long long>(m.iteration), static_cast<long long>(m.agent_steps), m.episodes,
                m.hider_reward, m.seeker_reward, m.policy_loss, m.value_loss, m.entropy, m.approx_kl,
                m.clip_frac, m.explained_variance, m.grad_norm, m.value_mean);
  return buf;
}

TEST(TrainConfig, RejectsBadValuesNamingTheField) {
  auto rejects = [](const std::string& key, const std::string& value, const std::string& needle) {
    TrainConfig c;
    try {
      c.set(key, value);
      c.validate();
    } catch (const physics::ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
      return;
    }
    ADD_FAILURE() << key << "=" << value << " was accepted";
  };
  rejects("epochs", "0", "epochs");
  rejects("lr", "-1", "lr");
  rejects("lr", "fast", "must be a finite number");
  rejects("envs", "2.5", "must be an integer");
  rejects("scene", "moon", "quadrant, full, empty, lockbox, lock-and-return, sequential-lock, shelter");
  rejects("model", "huge", "small, paper");
  rejects("bptt", "7", "must divide the rollout length");
  rejects("grad_groups", "0", "grad_groups");
  rejects("grad_groups", "2000", "must be in [1, 1024]");
  rejects("chunk_sequences", "-1",
          "chunk_sequences = '-1' is invalid: must be in [0, 1024] (0 = the model's)");
  rejects("chunk_sequences", "1025", "must be in [0, 1024]");
  rejects("precision", "fp16", "precision = 'fp16' is invalid: must be one of fp32, bf16, auto");
  rejects("colour", "red", "unknown key 'colour'");
  rejects("envs", "65536", "agent-step rows in the rollout buffer");  // 80 steps x 65536 envs x 6 slots
  rejects("minibatch_chunks", "-1", "minibatch_chunks");
  // The default buffer: 32 quadrant envs x 4 agent slots x 8 chunks of 10 steps.
  rejects("minibatch_chunks", "1025", "must be in [0, 1024]");
}

// Update blocks (gradient groups, the unit of a rank): min(grad_groups, envs), fewer where a block's share of
// a minibatch would not fill a training chunk (16 sequences here).
TEST(TrainConfig, UpdateBlocksFillATrainingChunk) {
  TrainConfig c;  // 32 quadrant envs x 4 slots x 8 chunks, 4 minibatches: 256 chunks each
  c.chunk_sequences = 16;
  EXPECT_EQ(c.update_blocks(), 8);
  c.grad_groups = 32;
  EXPECT_EQ(c.update_blocks(), 16);  // 16 chunks per block and minibatch
  c.envs = 8;                        // 64 chunks per minibatch
  EXPECT_EQ(c.update_blocks(), 4);
  c.minibatch_chunks = 16;  // 16 minibatches of 16 chunks
  EXPECT_EQ(c.update_blocks(), 1);
  c.minibatch_chunks = 0;
  c.grad_groups = 3;
  EXPECT_EQ(c.update_blocks(), 3);
  c.envs = 2;
  EXPECT_EQ(c.update_blocks(), 1);  // 16 chunks per minibatch in all: one block
  c.envs = 32;
  c.grad_groups = 32;
  c.minibatch_chunks = 128;  // 8 minibatches of 128 chunks
  EXPECT_EQ(c.update_blocks(), 8);
  c.chunk_sequences = 8;
  EXPECT_EQ(c.update_blocks(), 16);
  c.chunk_sequences = 0;  // the small model's chunk: 4 sequences
  EXPECT_EQ(c.train_chunk(), 4);
  EXPECT_EQ(c.update_blocks(), 32);
}

// The training chunk: chunk_sequences, 0 = the model's (4 for small, 16 for paper). A trainer and `hns train`
// write the chunk that runs in its place (so a run's files name it and resume with it); it changes results.
TEST(TrainConfig, ChunkSequencesZeroIsTheModelsChunk) {
  TrainConfig c;
  EXPECT_EQ(c.chunk_sequences, 0);
  EXPECT_EQ(c.train_chunk(), 4);
  c.model = "paper";
  EXPECT_EQ(c.train_chunk(), 16);
  c.chunk_sequences = 6;
  EXPECT_EQ(c.train_chunk(), 6);
  TrainConfig d = c;
  d.chunk_sequences = 16;
  EXPECT_NE(c.identity_mismatch(d).find("chunk_sequences"), std::string::npos);
  for (const char* model : {"small", "paper"}) {
    TrainConfig t = tiny_quadrant();
    t.model = model;
    const Trainer trainer(t);
    EXPECT_EQ(trainer.config().chunk_sequences, std::string(model) == "small" ? 4 : 16) << model;
    EXPECT_EQ(trainer.net().parallel().train_chunk_sequences, trainer.config().chunk_sequences) << model;
  }
}

// The paper sizes an update by its minibatch in chunks: minibatch_chunks splits each epoch into as many equal
// minibatches as it takes; without it `minibatches` does, never into more minibatches than chunks.
TEST(TrainConfig, MinibatchChunksSizesTheUpdate) {
  TrainConfig c;
  c.minibatches = 4;
  EXPECT_EQ(c.buffer_chunks(), 1024);
  EXPECT_EQ(c.minibatches_for(1024), 4);
  EXPECT_EQ(c.minibatches_for(3), 3);
  EXPECT_EQ(c.minibatches_for(0), 0);
  c.minibatch_chunks = 300;
  EXPECT_NO_THROW(c.validate());
  EXPECT_EQ(c.minibatches_for(1024), 4);  // 256 chunks each
  EXPECT_EQ(c.minibatches_for(900), 3);
  EXPECT_EQ(c.minibatches_for(901), 4);
  c.minibatch_chunks = 1024;
  EXPECT_EQ(c.minibatches_for(1024), 1);
  // It changes results: a checkpoint of another minibatch size is another run.
  TrainConfig d = c;
  d.minibatch_chunks = 512;
  EXPECT_NE(c.identity_mismatch(d).find("minibatch_chunks"), std::string::npos);
}

TEST(TrainConfig, JsonRoundTripAndMalformedFiles) {
  TrainConfig a;
  a.scene = "full";
  a.lr = 1.25e-4;
  a.seed = 99;
  a.chunk_sequences = 6;
  TrainConfig b;
  b.merge_json(a.to_json(), "test");
  EXPECT_EQ(a.to_json(), b.to_json());
  EXPECT_EQ(a.identity_mismatch(b), "");
  b.seed = 3;
  EXPECT_NE(a.identity_mismatch(b).find("seed"), std::string::npos);

  TrainConfig c;
  EXPECT_THROW(c.merge_json("{\"epochs\": 2,", "f.json"), physics::ConfigError);
  EXPECT_THROW(c.merge_json("{\"epochs\": [2]}", "f.json"), physics::ConfigError);
  EXPECT_THROW(c.merge_json("{\"epochs\": \"two\"}", "f.json"), physics::ConfigError);
  c.merge_json("{\"epochs\": 2, \"scene\": \"lockbox\"}", "f.json");
  EXPECT_EQ(c.epochs, 2);
  EXPECT_EQ(c.scene, "lockbox");
  EXPECT_EQ(c.grad_groups, 8);  // today's default
  // A run made before grad_groups existed used 16 groups: its config and checkpoint say so by omission.
  TrainConfig old_run;
  old_run.merge_run_json("{\"epochs\": 2}", "config.json");
  EXPECT_EQ(old_run.grad_groups, 16);
  EXPECT_EQ(old_run.chunk_sequences, 16);  // and chunks of 16 sequences, before chunk_sequences existed
  TrainConfig new_run;
  new_run.merge_run_json(a.to_json(), "config.json");
  EXPECT_EQ(new_run.grad_groups, a.grad_groups);
  EXPECT_EQ(new_run.chunk_sequences, 6);  // a key written is read back, not replaced by the old runs' 16
}

// The config reader takes what the writer writes (a control character in a path is written as \u0009, which
// must read back: a run must stay resumable) and refuses what JSON does not allow, naming the problem, with
// a long value cut short in the message.
TEST(TrainConfig, ReaderTakesJsonEscapesAndRefusesWhatJsonDoesNot) {
  TrainConfig a;
  a.init_from = "/tmp/with\ttab\x01and \"quote\" \\ back";
  TrainConfig b;
  b.merge_run_json(a.to_json(), "config.json");
  EXPECT_EQ(b.init_from, a.init_from);
  TrainConfig u;
  u.merge_json(R"({"scene": "\u0071uadrant", "init_from": "caf\u00e9 \ud83d\ude00 \b\f\r"})", "f.json");
  EXPECT_EQ(u.scene, "quadrant");
  EXPECT_EQ(u.init_from, "caf\xc3\xa9 \xf0\x9f\x98\x80 \b\f\r");
  auto refused = [](const std::string& text, const std::string& why) {
    TrainConfig c;
    try {
      c.merge_json(text, "f.json");
    } catch (const physics::ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos)
          << text.substr(0, 100) << ": " << e.what();
      EXPECT_LT(std::string(e.what()).size(), 600u) << "the message must not echo a huge value";
      return;
    }
    ADD_FAILURE() << "accepted: " << text.substr(0, 100);
  };
  refused(R"({"epochs": 2, "epochs": 3})", "epochs");  // duplicate key
  refused(R"({"scene": quadrant})", "quadrant");       // an unquoted word
  refused(R"({"epochs": 02})", "02");                  // a leading zero
  refused(R"({"epochs": "2"})", "epochs");             // a string for an integer
  refused(R"({"epochs": true})", "epochs");            // a boolean for an integer
  refused(R"({"lr": 0x1p-10})", "0x1p-10");            // not a JSON number
  refused(R"({"lr": +1})", "+1");
  refused(R"({"scene": "\u12"})", "escape");                                          // a broken \u escape
  refused("{\"epochs\": \"" + std::string(50'000, '7') + "\"}", "50000 characters");  // cut short
}

// precision: a run made before the key existed ran in fp32; the key is part of a run's identity; auto
// resolves to what the CPU has, and bf16 on a CPU without it is refused (ConfigError, exit 2 in hns train).
TEST(TrainConfig, PrecisionKeyResolvesPerCpu) {
  TrainConfig old_run;
  old_run.precision = "auto";
  old_run.merge_run_json("{\"epochs\": 2}", "config.json");
  EXPECT_EQ(old_run.precision, "fp32");
  TrainConfig bf;
  bf.set("precision", "bf16");
  EXPECT_NO_THROW(bf.validate());
  EXPECT_NE(bf.to_json().find("\"precision\": \"bf16\""), std::string::npos);
  TrainConfig back;
  back.merge_run_json(bf.to_json(), "config.json");
  EXPECT_EQ(back.precision, "bf16");
  EXPECT_NE(TrainConfig().identity_mismatch(bf).find("precision: checkpoint has fp32, this run has bf16"),
            std::string::npos);

  nn::CpuFeatures without, with;
  with.avx512_bf16 = true;
  EXPECT_THROW(nn::resolve_precision("bf16", without), std::invalid_argument);
  try {
    (void)bf.resolve_precision(without);
    ADD_FAILURE() << "bf16 was accepted on a CPU without AVX512-BF16";
  } catch (const physics::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("AVX512-BF16"), std::string::npos) << e.what();
  }
  EXPECT_EQ(bf.resolve_precision(with), nn::Precision::kBf16);
  TrainConfig autop;
  autop.precision = "auto";
  EXPECT_EQ(autop.resolve_precision(without), nn::Precision::kFp32);
  EXPECT_EQ(autop.resolve_precision(with), nn::Precision::kBf16);
  EXPECT_EQ(TrainConfig().resolve_precision(with), nn::Precision::kFp32);
  TrainConfig bad;
  bad.precision = "fp16";
  EXPECT_THROW((void)bad.resolve_precision(with), physics::ConfigError);

  // A trainer names the precision that runs (auto resolved), in its config and its first metrics row.
  TrainConfig c = tiny_quadrant();
  c.precision = "auto";
  Trainer t(c);
  const std::string runs(nn::precision_name(nn::resolve_precision("auto")));
  EXPECT_EQ(t.config().precision, runs);
  EXPECT_EQ(std::string(nn::precision_name(t.net().precision())), runs);
}

TEST(ScalarNormalizer, DebiasedMeanAndFlooredStd) {
  ScalarNormalizer n;
  EXPECT_EQ(n.mean(), 0.0);
  EXPECT_EQ(n.std(), 1.0);
  n.update(4.0, 16.0 + 9.0);  // mean 4, variance 9
  EXPECT_NEAR(n.mean(), 4.0, 1e-9);
  EXPECT_NEAR(n.std(), 3.0, 1e-6);
  ScalarNormalizer c;
  c.update(2.0, 4.0);
  EXPECT_NEAR(c.std(), 0.1, 1e-9);
}

TEST(Trainer, RunsAnIterationWithFiniteDiagnostics) {
  Trainer t(tiny_quadrant());
  const IterationMetrics m = t.iterate();
  EXPECT_EQ(m.iteration, 1);
  EXPECT_EQ(m.agent_steps, 3 * 4 * 20);  // 3 envs x 2v2 x 20 steps, no padding in the quadrant game
  EXPECT_EQ(m.episodes, 3);
  EXPECT_TRUE(std::isfinite(m.policy_loss));
  EXPECT_GT(m.entropy, 5.0);  // 3 x ln 11 + 2 x ln 2 = 8.58 for a fresh policy
  EXPECT_LT(m.entropy, 8.6);
  EXPECT_GE(m.clip_frac, 0.0);
  EXPECT_GT(m.value_loss, 0.0);
  // Zero-sum teams in the quadrant game, out-of-bounds penalties aside.
  EXPECT_NE(m.hider_reward, 0.0);
  // The time split adds up, and the metrics line carries every part of it.
  EXPECT_GT(m.t_backward, 0.0);
  EXPECT_LE(m.t_targets + m.t_backward + m.t_optimizer, m.t_learn + 1e-6);
  const std::string json = m.to_json();
  auto field = [&](const std::string& key) {
    const size_t at = json.find("\"" + key + "\": ");
    EXPECT_NE(at, std::string::npos) << key;
    return at == std::string::npos ? -1.0 : std::stod(json.substr(at + key.size() + 4));
  };
  EXPECT_NEAR(field("time_backward"), m.t_backward, 1e-4);
  EXPECT_NEAR(field("time_optimizer"), m.t_optimizer, 1e-4);
  EXPECT_NEAR(field("time_other"), m.t_other, 1e-4);
  EXPECT_NEAR(field("policy_loss"), m.policy_loss, 1e-5 * (1 + std::abs(m.policy_loss)));
  EXPECT_EQ(field("unstable_resets"), double(m.unstable_resets));
  // The first row names the networks' precision; later rows do not repeat it.
  EXPECT_NE(json.find("\"precision\": \"fp32\""), std::string::npos) << json;
  EXPECT_EQ(t.iterate().to_json().find("precision"), std::string::npos);
}

// The rollout normalises each key of a step's observations with that key's statistics as it copies them:
// the network acting on those rows (identity view) gives the bits of the network acting on the raw rows and
// normalising them itself.
TEST(ObsStore, CopyStepNormalisesEachKeyWithItsStatistics) {
  TrainConfig c = tiny_quadrant();
  Trainer t(c);
  t.iterate();  // a normaliser that is not the identity
  const nn::ActorCritic& net = t.net();
  const nn::ObsShape& shape = net.config().obs;
  const int G = c.envs * shape.max_agents;
  const nn::ObsNormView view = t.obs_normalizer().view();
  ASSERT_NE(view.mean[nn::kObsSelf][0], 0.0f);
  const StepObsView step = StepObsView::of(t.sim().state());
  nn::ObsStore normalised(shape, size_t(G)), raw(shape, size_t(G));
  normalised.copy_step(step, size_t(G), 0, &view);
  raw.copy_step(step, size_t(G), 0);
  EXPECT_NE(std::memcmp(normalised.self.data(), raw.self.data(), sizeof(float) * normalised.self.size()), 0);
  const int sw = net.state_width(), nh = net.heads().num_heads(), nl = net.heads().num_logits();
  auto logits_of = [&](const nn::ObsStore& o, const nn::ObsNormView& v) {
    std::vector<float> ps(size_t(G) * sw, 0.0f), vs = ps, logits(size_t(G) * nl);
    const std::vector<float> uniforms(size_t(G) * nh, 0.5f);
    std::vector<int32_t> actions(size_t(G) * nh);
    net.act(v, o.batch(), G, ps.data(), vs.data(), uniforms.data(),
            {actions.data(), nullptr, nullptr, logits.data()});
    return logits;
  };
  EXPECT_EQ(logits_of(normalised, nn::ObsNormView::identity()), logits_of(raw, view));
}

// The determinism tests below run for both precisions of the networks' products (bf16 where this CPU has
// AVX512-BF16).
class TrainerPrecision : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam() == "bf16" && !nn::CpuFeatures::detect().avx512_bf16)
      GTEST_SKIP() << "this CPU has no AVX512-BF16: bf16 training cannot run here";
  }
  TrainConfig tiny() const {
    TrainConfig c = tiny_quadrant();
    c.precision = GetParam();
    return c;
  }
};
INSTANTIATE_TEST_SUITE_P(Precisions, TrainerPrecision, ::testing::Values("fp32", "bf16"),
                         [](const ::testing::TestParamInfo<std::string>& info) { return info.param; });

TEST_P(TrainerPrecision, BitIdenticalForAnyThreadCount) {
  TrainConfig c1 = tiny();
  TrainConfig c2 = c1;
  c2.threads = 2;
  Trainer a(c1), b(c2);
  for (int i = 0; i < 2; ++i) EXPECT_EQ(results_of(a.iterate()), results_of(b.iterate()));
  EXPECT_EQ(params_of(a), params_of(b));
}

// With one epoch of one minibatch the update sees exactly the rollout's parameters and normalisation, so
// the log-probabilities it recomputes (BPTT chunks of 10 steps, training chunk sizes) equal those the
// rollout sampled with (one step at a time): every ratio is 1, the KL estimate 0, nothing clipped. In later
// iterations too (the observation normaliser moves only after the update), and with padding agents.
TEST_P(TrainerPrecision, FirstMinibatchRecomputesTheRolloutsLogProbabilities) {
  TrainConfig full = tiny();
  full.scene = "full";
  full.horizon = 30;
  full.envs = 2;
  for (TrainConfig config : {tiny(), full}) {
    config.epochs = 1;
    config.minibatches = 1;
    Trainer t(config);
    for (int i = 0; i < 3; ++i) {
      const IterationMetrics m = t.iterate();
      EXPECT_EQ(m.approx_kl, 0.0) << config.scene << ", iteration " << i + 1;
      EXPECT_EQ(m.clip_frac, 0.0) << config.scene << ", iteration " << i + 1;
      EXPECT_GT(m.entropy, 1.0);
    }
  }
}

// An iteration's metrics line without its timings (wall seconds, rates and the time split).
std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Resuming from the checkpoint of every iteration continues exactly as the uninterrupted run: the same
// checkpoint bytes after each later iteration (weights, Adam's moments and step, both normalisers, episode
// counters; the random streams derive from the iteration) and the same metrics but timings. In the quadrant
// game and in the full game with padding agents, long enough that boxes end episodes locked.
TEST_P(TrainerPrecision, ResumeAfterEveryIterationIsBitIdentical) {
  TrainConfig full = tiny();
  full.scene = "full";
  full.horizon = 30;
  full.envs = 2;
  for (const TrainConfig& config : {tiny(), full}) {
    const int iterations = 5;
    Trainer straight(config);
    std::vector<std::string> metrics, checkpoints;
    double boxes_locked = 0;
    int padded = 0;
    for (int i = 0; i < iterations; ++i) {
      const IterationMetrics m = straight.iterate();
      metrics.push_back(metrics_but_timings(m));
      boxes_locked += m.num_box_lock;
      const std::string path =
          temp_path("resume_" + GetParam() + "_" + config.scene + std::to_string(i + 1) + ".bin");
      straight.save(path);
      checkpoints.push_back(path);
      const batch::BatchState& s = straight.sim().state();
      for (size_t a = 0; a < s.agent_exists.size(); ++a) padded += s.agent_exists.data()[a] == 0;
    }
    EXPECT_GT(boxes_locked, 0.0) << config.scene << ": boxes must end episodes locked";
    if (config.scene == "full") {
      EXPECT_GT(padded, 0) << "the full game must have padding agent slots";
    }
    for (int from = 1; from < iterations; ++from) {
      Trainer resumed(config);
      resumed.load(checkpoints[from - 1]);
      ASSERT_EQ(resumed.iteration(), from);
      for (int i = from; i < iterations; ++i) {
        const IterationMetrics m = resumed.iterate();
        EXPECT_EQ(metrics_but_timings(m), metrics[i]) << config.scene << ": resumed after " << from;
        const std::string path = temp_path("resumed_" + GetParam() + "_" + config.scene + ".bin");
        resumed.save(path);
        EXPECT_TRUE(file_bytes(path) == file_bytes(checkpoints[i]))
            << config.scene << ": checkpoint after iteration " << i + 1 << ", resumed after " << from;
        std::remove(path.c_str());
      }
    }
    for (const std::string& path : checkpoints) std::remove(path.c_str());
  }
}

// The count keys fix a hide-and-seek scene's teams and objects (the paper's single-agent count-based
// baselines): the lone agent keeps an empty other-agent slot, and a scene whose ramps are set to 0 an empty
// ramp slot, so its checkpoint still starts a transfer task; the keys are written only where set, read back,
// compared on resume, and refused by the transfer tasks.
TEST(TrainConfig, CountKeysFixTheTeamsAndKeepTheEntityTypes) {
  TrainConfig c = tiny_quadrant();
  c.set("hiders", "1");
  c.set("seekers", "0");
  c.set("ramps", "0");
  c.set("boxes", "3");
  c.validate();
  const batch::BatchConfig game = c.batch_config();
  const physics::WorldConfig& w = game.world;
  EXPECT_EQ(w.max_agents(), 1);
  EXPECT_EQ(game.agent_slots(), 2);
  EXPECT_EQ(game.rules.obs_min_ramps, 1);
  EXPECT_EQ(w.scene.boxes.min, 3);
  EXPECT_EQ(w.scene.boxes.max, 3);
  EXPECT_EQ(w.scene.ramps.max, 0);
  const std::string json = c.to_json();
  EXPECT_NE(json.find("\"hiders\": 1"), std::string::npos) << json;
  EXPECT_NE(json.find("\"seekers\": 0"), std::string::npos) << json;
  TrainConfig back;
  back.merge_run_json(json, "config.json");
  EXPECT_EQ(back.identity_mismatch(c), "");
  EXPECT_EQ(back.hiders, 1);
  EXPECT_EQ(back.boxes, 3);
  TrainConfig plain = tiny_quadrant();
  EXPECT_EQ(plain.to_json().find("hiders"), std::string::npos);  // files of runs without them are unchanged
  EXPECT_NE(plain.identity_mismatch(c).find("hiders"), std::string::npos);

  // A single-agent run trains, and its checkpoint starts lock-and-return (same entity types).
  const std::string path = temp_path("single_agent.bin");
  {
    Trainer single(c);
    const IterationMetrics m = single.iterate();
    EXPECT_EQ(m.agent_steps, int64_t(c.envs) * c.world().horizon);  // one real agent per env
    single.save(path);
  }
  TrainConfig lr;
  lr.scene = "lock-and-return";
  lr.envs = 2;
  lr.threads = 1;
  lr.init_from = path;
  Trainer t(lr);
  EXPECT_NE(t.initialize_from(path).find("policy weights"), std::string::npos);
  std::remove(path.c_str());

  TrainConfig task = lr;
  task.init_from.clear();
  task.hiders = 1;
  try {
    task.validate();
    ADD_FAILURE() << "a transfer task accepted a count key";
  } catch (const physics::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("are for the hide-and-seek scenes"), std::string::npos) << e.what();
  }
  task.hiders = -1;
  task.spawn_quarter = 1;
  EXPECT_THROW(task.validate(), physics::ConfigError);
  TrainConfig quarter = tiny_quadrant();
  quarter.set("spawn_quarter", "true");
  EXPECT_TRUE(quarter.world().scene.spawn_quarter);
  EXPECT_NE(quarter.to_json().find("\"spawn_quarter\": 1"), std::string::npos);
  EXPECT_FALSE(tiny_quadrant().world().scene.spawn_quarter);
  quarter.spawn_quarter = 2;
  EXPECT_THROW(quarter.validate(), physics::ConfigError);
  TrainConfig nobody = tiny_quadrant();
  nobody.hiders = 0;
  nobody.seekers = 0;
  EXPECT_THROW(nobody.validate(), physics::ConfigError);
  TrainConfig bad = tiny_quadrant();
  bad.seekers = -2;
  EXPECT_THROW(bad.validate(), physics::ConfigError);
  TrainConfig boxless = tiny_quadrant();
  boxless.boxes = 0;  // would drop the network's box type
  EXPECT_THROW(boxless.validate(), physics::ConfigError);
}

TEST(Trainer, NonFiniteLossStopsWithNumericalError) {
  TrainConfig c = tiny_quadrant();
  c.inject_nan_at = 2;
  Trainer t(c);
  EXPECT_NO_THROW(t.iterate());
  const std::vector<float> before = params_of(t);
  EXPECT_THROW(t.iterate(), NumericalError);
  // The poisoned update was skipped by Adam: the parameters are still those after iteration 1.
  EXPECT_EQ(params_of(t), before);
}

}  // namespace
}  // namespace hns::ppo
