// The PPO trainer: config validation, checkpoints (round trip, bit-identical resume, refusal of corrupt or
// foreign files), determinism across thread counts, the NaN stop, and the value-target normaliser.
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

namespace hns::ppo {
namespace {

// Two agents a side in the quadrant game, a few envs: small and quick, yet every part of the loop runs.
TrainConfig tiny_quadrant() {
  TrainConfig c;
  c.scene = "quadrant";
  c.model = "small";
  c.envs = 3;
  c.horizon = 20;
  c.epochs = 2;
  c.minibatches = 2;
  c.threads = 1;
  c.seed = 7;
  return c;
}

std::vector<float> params_of(const Trainer& t) {
  const float* p = t.net().params().values();
  return {p, p + t.net().params().buffer_floats()};
}

// Everything of an iteration's metrics that does not depend on wall time.
std::string results_of(const IterationMetrics& m) {
  char buf[512];
  std::snprintf(buf, sizeof buf, "%lld %lld %d %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g",
                static_cast<long long>(m.iteration), static_cast<long long>(m.agent_steps), m.episodes,
                m.hider_reward, m.seeker_reward, m.policy_loss, m.value_loss, m.entropy, m.approx_kl,
                m.clip_frac, m.explained_variance, m.grad_norm, m.value_mean);
  return buf;
}

// Named by the process too: two test runs on one machine (two build trees, ctest -j) must not share files.
std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("hns_trainer_test_" + std::to_string(::getpid()) + "_" + name))
      .string();
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
  rejects("precision", "fp16", "precision = 'fp16' is invalid: must be one of fp32, bf16, auto");
  rejects("colour", "red", "unknown key 'colour'");
  rejects("envs", "65536", "agent-step rows in the rollout buffer");  // 80 steps x 65536 envs x 6 slots
  rejects("minibatch_chunks", "-1", "minibatch_chunks");
  // The default buffer: 32 quadrant envs x 4 agent slots x 8 chunks of 10 steps.
  rejects("minibatch_chunks", "1025", "must be in [0, 1024]");
}

// Update blocks (gradient groups, the unit of a rank): min(grad_groups, envs), fewer where a block's share of
// a minibatch would not fill a 16-sequence chunk.
TEST(TrainConfig, UpdateBlocksFillATrainingChunk) {
  TrainConfig c;  // 32 quadrant envs x 4 slots x 8 chunks, 4 minibatches: 256 chunks each
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
  TrainConfig new_run;
  new_run.merge_run_json(a.to_json(), "config.json");
  EXPECT_EQ(new_run.grad_groups, a.grad_groups);
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
std::string metrics_but_timings(const IterationMetrics& m) {
  IterationMetrics untimed = m;
  untimed.seconds = untimed.steps_per_s = 0;
  untimed.t_simulate = untimed.t_observe = untimed.t_infer = untimed.t_learn = untimed.t_other = 0;
  untimed.t_targets = untimed.t_backward = untimed.t_optimizer = untimed.t_intrinsic = 0;
  return untimed.to_json();
}

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

TEST(Trainer, RefusesCorruptTruncatedAndForeignCheckpoints) {
  const std::string path = temp_path("corrupt.bin");
  TrainConfig cfg = tiny_quadrant();
  {
    Trainer t(cfg);
    t.iterate();
    t.save(path);
    t.save(path);  // over an existing checkpoint
    EXPECT_FALSE(std::filesystem::exists(path + ".tmp")) << "the temporary file is renamed";
    // A checkpoint that cannot be written says so and leaves nothing behind.
    const std::string nowhere = temp_path("no-such-folder") + "/checkpoint.bin";
    try {
      t.save(nowhere);
      ADD_FAILURE() << "saved into a missing folder";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("no-such-folder"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(std::filesystem::exists(nowhere + ".tmp"));
  }
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto expect_refused = [&](const std::string& content, const TrainConfig& c, const std::string& needle) {
    {
      std::ofstream out(path, std::ios::binary | std::ios::trunc);
      out.write(content.data(), std::streamsize(content.size()));
    }
    Trainer t(c);
    const std::vector<float> before = params_of(t);
    try {
      t.load(path);
      ADD_FAILURE() << "accepted a checkpoint that should fail with: " << needle;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
    EXPECT_EQ(params_of(t), before);  // a refused file changes nothing
    EXPECT_EQ(t.iteration(), 0);
  };
  std::string flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x10;
  expect_refused(flipped, cfg, "checksum mismatch");
  expect_refused(bytes.substr(0, bytes.size() - 100), cfg, "truncated");
  expect_refused("not a checkpoint at all", cfg, "not an hns checkpoint");
  std::string other_version = bytes;
  other_version[8] = 9;
  expect_refused(other_version, cfg, "format version 9");
  TrainConfig other = cfg;
  other.seed = 8;
  expect_refused(bytes, other, "seed: checkpoint has 7, this run has 8");
  TrainConfig paper = cfg;
  paper.model = "paper";
  expect_refused(bytes, paper, "model");
  // Impossible values under a valid checksum (the payload edited and re-summed) are refused too.
  constexpr size_t kHeader = 8 + 4 + 8;
  auto resummed = [&](const std::function<void(std::string&, size_t)>& edit) {
    std::string payload = bytes.substr(kHeader, bytes.size() - kHeader - 8);
    uint64_t config_bytes = 0;
    std::memcpy(&config_bytes, payload.data(), 8);
    edit(payload, 8 + config_bytes);  // the offset of the iteration counter
    const uint64_t sum = fnv1a64(payload.data(), payload.size());
    return bytes.substr(0, kHeader) + payload + std::string(reinterpret_cast<const char*>(&sum), 8);
  };
  expect_refused(resummed([](std::string& p, size_t at) {
                   const int64_t minus = -3;
                   std::memcpy(p.data() + at, &minus, 8);
                 }),
                 cfg, "the iteration is -3");
  expect_refused(resummed([&](std::string& p, size_t at) {
                   // iteration, agent and env steps, need_restart, the episode list (length + envs int32s),
                   // then the parameter buffer's length and its first value.
                   const size_t first_param = at + 3 * 8 + 1 + 8 + 4 * size_t(cfg.envs) + 8;
                   const float nan = std::numeric_limits<float>::quiet_NaN();
                   std::memcpy(p.data() + first_param + 4 * 5, &nan, 4);
                 }),
                 cfg, "the parameter buffer has nan at index 5");
  // An episode counter the run would overflow when it counts on (int32: 2^31 - 1 is near the end).
  expect_refused(resummed([&](std::string& p, size_t at) {
                   const int32_t near_end = std::numeric_limits<int32_t>::max();
                   std::memcpy(p.data() + at + 3 * 8 + 1 + 8, &near_end, 4);
                 }),
                 cfg, "env 0's episode count is 2147483647 (at most 2^30)");
  std::remove(path.c_str());
}

// An exported policy (Trainer::export_policy, `hns export`): about a third of the checkpoint; acts exactly as
// the checkpoint it came from (the same actions on the same observations, step after step); starts a run
// with --init-from as the checkpoint does (init_optimizer = 0), and is refused, saying why, where a full
// checkpoint is needed (resume, init_optimizer = 1) or when exported again.
TEST(Trainer, ExportedPolicyActsAsItsCheckpointAndOnlyStartsRuns) {
  const std::string ckpt = temp_path("export_source.bin"), exported = temp_path("export.hnspolicy");
  TrainConfig cfg = tiny_quadrant();
  Trainer source(cfg);
  source.iterate();
  source.iterate();
  source.save(ckpt);
  const uint64_t bytes = Trainer::export_policy(ckpt, exported);
  EXPECT_EQ(bytes, std::filesystem::file_size(exported));
  EXPECT_LT(double(bytes), 0.4 * double(std::filesystem::file_size(ckpt)));
  EXPECT_EQ(Trainer::checkpoint_config(exported).to_json(), Trainer::checkpoint_config(ckpt).to_json());

  // The same actions on the same observations, over whole episodes.
  const std::unique_ptr<Policy> from_ckpt = Policy::from_checkpoint(ckpt, 5);
  const std::unique_ptr<Policy> from_export = Policy::from_checkpoint(exported, 5);
  batch::BatchConfig bc;
  bc.world = cfg.world();
  bc.num_envs = 2;
  batch::BatchSim sim(bc);
  sim.reset();
  const size_t n = size_t(bc.num_envs) * size_t(sim.layout().max_agents);
  std::vector<physics::AgentAction> a(n), b(n);
  int differ = 0;
  for (int step = 0; step < 2 * cfg.horizon; ++step) {
    from_ckpt->act(sim, a);
    from_export->act(sim, b);
    for (size_t i = 0; i < n; ++i) differ += std::memcmp(&a[i], &b[i], sizeof a[i]) != 0;
    sim.step(a);
  }
  EXPECT_EQ(differ, 0);

  // A run started from either: the same weights and normalisers.
  TrainConfig start = tiny_quadrant();
  start.seed = 11;
  Trainer t1(start), t2(start);
  t1.initialize_from(ckpt);
  EXPECT_NE(t2.initialize_from(exported).find("policy weights"), std::string::npos);
  EXPECT_EQ(params_of(t1), params_of(t2));
  EXPECT_EQ(t1.value_normalizer().biased_sq, t2.value_normalizer().biased_sq);

  auto refused = [&](auto&& f, const std::string& says) {
    try {
      f();
      ADD_FAILURE() << "not refused; expected a message with: " << says;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  Trainer resumed(cfg);
  refused([&] { resumed.load(exported); }, "is an exported policy");
  start.init_optimizer = 1;
  Trainer with_adam(start);
  refused([&] { with_adam.initialize_from(exported); }, "init_optimizer = 1 needs Adam's moments");
  refused([&] { Trainer::export_policy(exported, temp_path("again.hnspolicy")); },
          "already an exported policy");
  // A damaged export is refused as a damaged checkpoint is.
  std::string file;
  {
    std::ifstream in(exported, std::ios::binary);
    file.assign(std::istreambuf_iterator<char>(in), {});
  }
  file[file.size() / 2] ^= 0x10;
  {
    std::ofstream out(exported, std::ios::binary);
    out << file;
  }
  refused([&] { (void)Policy::from_checkpoint(exported, 5); }, "checksum mismatch");
  std::filesystem::remove(ckpt);
  std::filesystem::remove(exported);
}

// `hns train --init-from`: a new run starts from a checkpoint's weights, normalisers and optimiser as its
// init_* keys say, and refuses another network.
TEST(Trainer, InitializeFromCarriesWhatItsKeysSay) {
  const std::string path = temp_path("init_source.bin");
  TrainConfig source_cfg = tiny_quadrant();
  Trainer source(source_cfg);
  source.iterate();
  source.iterate();
  source.save(path);
  const std::vector<float> trained = params_of(source);
  const nn::ParamLayout& layout = source.net().params().layout();
  auto is_value = [](const nn::ParamSlice& s) { return s.name.rfind("value/", 0) == 0; };
  auto floats = [](const nn::FloatBuffer& b) { return std::vector<float>(b.data(), b.data() + b.size()); };

  TrainConfig cfg = tiny_quadrant();
  cfg.seed = 11;  // other initial weights: what is carried must come from the checkpoint
  cfg.envs = 2;   // and another env count than the source's 3
  cfg.init_from = path;
  for (int init_value : {1, 0}) {
    for (int norms : {1, 0}) {
      for (int optimizer : {0, 1}) {
        cfg.init_value = init_value;
        cfg.init_normalizers = norms;
        cfg.init_optimizer = optimizer;
        if (optimizer == 1 && init_value == 0) {  // Adam's state is one for both networks
          EXPECT_THROW(Trainer{cfg}, physics::ConfigError);
          continue;
        }
        Trainer fresh(cfg);
        Trainer t(cfg);
        const std::string said = t.initialize_from(path);
        EXPECT_NE(said.find("policy weights"), std::string::npos) << said;
        EXPECT_EQ(t.iteration(), 0);
        const std::vector<float> got = params_of(t), seeded = params_of(fresh);
        for (const nn::ParamSlice& slice : layout.slices()) {
          const bool carried = !is_value(slice) || init_value == 1;
          const std::vector<float>& want = carried ? trained : seeded;
          EXPECT_TRUE(std::equal(got.begin() + long(slice.offset),
                                 got.begin() + long(slice.offset + slice.size()),
                                 want.begin() + long(slice.offset)))
              << slice.name << " init_value=" << init_value;
        }
        const Trainer& norm_from = norms ? source : fresh;
        for (int k = 0; k < nn::kNumObsKeys; ++k) {
          const auto key = nn::ObsKey(k);
          EXPECT_EQ(t.obs_normalizer().biased_mean(key), norm_from.obs_normalizer().biased_mean(key));
          EXPECT_EQ(t.obs_normalizer().biased_sq(key), norm_from.obs_normalizer().biased_sq(key));
          EXPECT_EQ(t.obs_normalizer().debias(key), norm_from.obs_normalizer().debias(key));
        }
        const ScalarNormalizer& vn = (norms && init_value ? source : fresh).value_normalizer();
        EXPECT_EQ(t.value_normalizer().biased_mean, vn.biased_mean);
        EXPECT_EQ(t.value_normalizer().biased_sq, vn.biased_sq);
        EXPECT_EQ(t.value_normalizer().debias, vn.debias);
        const Trainer& adam_from = optimizer ? source : fresh;
        EXPECT_EQ(t.optimizer().steps(), adam_from.optimizer().steps());
        EXPECT_EQ(floats(t.optimizer().m()), floats(adam_from.optimizer().m()));
        EXPECT_EQ(floats(t.optimizer().v()), floats(adam_from.optimizer().v()));
      }
    }
  }
  // The run it starts goes on and resumes like any other, bit for bit.
  cfg.init_value = 1;
  cfg.init_normalizers = 1;
  cfg.init_optimizer = 0;
  Trainer started(cfg);
  started.initialize_from(path);
  started.iterate();
  const std::string mid = temp_path("init_mid.bin");
  started.save(mid);
  const std::string second = metrics_but_timings(started.iterate());
  Trainer resumed(cfg);
  resumed.load(mid);
  EXPECT_EQ(metrics_but_timings(resumed.iterate()), second);

  auto expect_refused = [&](TrainConfig c, const std::string& needle) {
    c.init_from = path;
    Trainer t(c);
    const std::vector<float> before = params_of(t);
    try {
      t.initialize_from(path);
      ADD_FAILURE() << "started from a checkpoint that should fail with: " << needle;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
    EXPECT_EQ(params_of(t), before);
  };
  TrainConfig paper = tiny_quadrant();
  paper.model = "paper";
  expect_refused(paper, "model: checkpoint has small, this run has paper");
  TrainConfig lockbox = tiny_quadrant();
  lockbox.scene = "lockbox";
  expect_refused(lockbox,
                 "observation slots: the checkpoint's scene quadrant has 3 other agents, 2 boxes, 1 ramps");

  // The transfer tasks (and the full game) have the quadrant policy's entity types, in other counts: its
  // policy weights act there unchanged, and the run goes on.
  for (const char* scene : {"full", "lock-and-return", "sequential-lock"}) {
    TrainConfig c = tiny_quadrant();
    c.scene = scene;
    c.init_from = path;
    Trainer t(c);
    EXPECT_NE(t.initialize_from(path).find("policy weights"), std::string::npos) << scene;
    const std::vector<float> got = params_of(t);
    for (const nn::ParamSlice& slice : t.net().params().layout().slices()) {
      if (is_value(slice)) continue;
      EXPECT_TRUE(std::equal(got.begin() + long(slice.offset),
                             got.begin() + long(slice.offset + slice.size()),
                             trained.begin() + long(slice.offset)))
          << scene << " " << slice.name;
    }
    EXPECT_NO_THROW(t.iterate()) << scene;
  }
  std::remove(path.c_str());
  std::remove(mid.c_str());
}

// Blueprint has a fourth entity type, its construction sites. A hide-and-seek checkpoint starts it: every
// slice the checkpoint has is carried by name, the site embeddings and the sites' normaliser statistics keep
// the new run's seed (Adam's state cannot be carried then), and the run goes on and resumes bit for bit, its
// checkpoint holding the sites. A blueprint checkpoint cannot start a scene without sites.
TEST(Trainer, BlueprintStartsFromAHideAndSeekCheckpointWithItsSiteEmbeddingFromTheSeed) {
  const std::string path = temp_path("init_blueprint.bin");
  Trainer source(tiny_quadrant());
  source.iterate();
  source.save(path);
  const nn::ParamLayout& from = source.net().params().layout();
  const std::vector<float> trained = params_of(source);
  auto floats = [](const nn::FloatBuffer& b) { return std::vector<float>(b.data(), b.data() + b.size()); };

  TrainConfig cfg = tiny_quadrant();
  cfg.scene = "blueprint";
  cfg.seed = 11;
  cfg.init_from = path;
  cfg.init_optimizer = 1;  // Adam's step count cannot serve slices that start from the seed
  {
    Trainer refused(cfg);
    const std::vector<float> before = params_of(refused);
    try {
      refused.initialize_from(path);
      ADD_FAILURE() << "init_optimizer = 1 with new site embeddings";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(
          std::string(e.what()).find("init_optimizer = 1: the checkpoint lacks this run's site embeddings"),
          std::string::npos)
          << e.what();
    }
    EXPECT_EQ(params_of(refused), before);
  }
  cfg.init_optimizer = 0;
  Trainer fresh(cfg);
  Trainer t(cfg);
  const std::string said = t.initialize_from(path);
  EXPECT_NE(said.find("slices the checkpoint lacks from the seed"), std::string::npos) << said;
  const std::vector<float> got = params_of(t), seeded = params_of(fresh);
  const std::vector<float> got_m = floats(t.optimizer().m()), seeded_m = floats(fresh.optimizer().m());
  int site_slices = 0;
  for (const nn::ParamSlice& slice : t.net().params().layout().slices()) {
    const auto at = [&](const std::vector<float>& v, size_t offset) { return v.begin() + long(offset); };
    const nn::ParamSlice* old = from.find(slice.name);
    if (slice.name.find("/embed_sites/") != std::string::npos) {
      ++site_slices;
      ASSERT_EQ(old, nullptr) << slice.name;
      EXPECT_TRUE(
          std::equal(at(got, slice.offset), at(got, slice.offset + slice.size()), at(seeded, slice.offset)))
          << slice.name;
      continue;
    }
    ASSERT_NE(old, nullptr) << slice.name;
    EXPECT_TRUE(
        std::equal(at(got, slice.offset), at(got, slice.offset + slice.size()), at(trained, old->offset)))
        << slice.name;
    EXPECT_TRUE(std::equal(at(got_m, slice.offset), at(got_m, slice.offset + slice.size()),
                           at(seeded_m, slice.offset)))
        << slice.name << ": Adam's moments start fresh";
  }
  EXPECT_EQ(site_slices, 4);  // kernel and bias of the policy's and the value net's site embedding
  for (int k = 0; k < nn::kNumObsKeys; ++k) {
    const auto key = nn::ObsKey(k);
    const Trainer& want = key == nn::kObsSites ? fresh : source;
    EXPECT_EQ(t.obs_normalizer().biased_mean(key), want.obs_normalizer().biased_mean(key)) << k;
    EXPECT_EQ(t.obs_normalizer().debias(key), want.obs_normalizer().debias(key)) << k;
  }
  EXPECT_EQ(t.obs_normalizer().features(nn::kObsSites), 15);

  t.iterate();
  EXPECT_GT(t.obs_normalizer().debias(nn::kObsSites), 0.0) << "the sites' statistics are learned";
  const std::string mid = temp_path("init_blueprint_mid.bin");
  t.save(mid);
  const std::string second = metrics_but_timings(t.iterate());
  Trainer resumed(cfg);
  resumed.load(mid);
  EXPECT_EQ(metrics_but_timings(resumed.iterate()), second);
  EXPECT_EQ(params_of(resumed), params_of(t));

  TrainConfig back = tiny_quadrant();
  back.init_from = mid;
  Trainer q(back);
  try {
    q.initialize_from(mid);
    ADD_FAILURE() << "a blueprint checkpoint started a quadrant run";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("(sites may be added)"), std::string::npos) << e.what();
  }
  std::remove(path.c_str());
  std::remove(mid.c_str());
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
  const physics::WorldConfig w = c.world();
  EXPECT_EQ(w.max_agents(), 1);
  EXPECT_EQ(w.agent_slots(), 2);
  EXPECT_EQ(w.obs_min_ramps, 1);
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

// The paper's fine-tuning reinitialises each network's final layer norm and output layer: with init_heads = 0
// exactly those slices (policy and value) keep the new run's seeded values, every other slice is carried.
TEST(Trainer, InitHeadsZeroStartsTheHeadsFromTheSeed) {
  const std::string path = temp_path("init_heads.bin");
  Trainer source(tiny_quadrant());
  source.iterate();
  source.save(path);
  const std::vector<float> trained = params_of(source);
  TrainConfig cfg = tiny_quadrant();
  cfg.seed = 12;
  cfg.init_from = path;
  cfg.init_heads = 0;
  Trainer fresh(cfg);
  const std::vector<float> seeded = params_of(fresh);
  Trainer t(cfg);
  EXPECT_NE(t.initialize_from(path).find("heads from the seed"), std::string::npos);
  const std::vector<float> got = params_of(t);
  std::vector<std::string> heads;
  for (const nn::ParamSlice& slice : t.net().params().layout().slices()) {
    const bool head = slice.name.find("/out_norm/") != std::string::npos ||
                      slice.name.rfind("policy/logits/", 0) == 0 || slice.name.rfind("value/value/", 0) == 0;
    if (head) heads.push_back(slice.name);
    const std::vector<float>& want = head ? seeded : trained;
    EXPECT_TRUE(std::equal(got.begin() + long(slice.offset), got.begin() + long(slice.offset + slice.size()),
                           want.begin() + long(slice.offset)))
        << slice.name << (head ? " (a head: from the seed)" : " (carried)");
  }
  EXPECT_EQ(heads.size(), 8u);  // out_norm gain and bias, output weights and bias, in each network
  std::remove(path.c_str());
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
