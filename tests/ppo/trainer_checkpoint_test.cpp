// The trainer's checkpoints: refusal of corrupt, truncated and foreign files, exported policies, starting a
// run from another run's checkpoint (initialize_from, init_heads; a hide-and-seek checkpoint into
// blueprint). Config validation, determinism and bit-identical resume are in trainer_test.cpp.
#include <gtest/gtest.h>

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

#include "physics/scene.hpp"
#include "ppo/atomic_file.hpp"
#include "ppo/policy.hpp"
#include "ppo/trainer.hpp"
#include "ppo_test_util.hpp"

namespace hns::ppo {
namespace {

using testing::metrics_but_timings;
using testing::params_of;
using testing::temp_path;
using testing::tiny_quadrant;

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
// checkpoint is needed (resume, init_optimizer = 1) or when exported again. The export names the file its
// run started from by folder and file name only, without the training machine's directories.
TEST(Trainer, ExportedPolicyActsAsItsCheckpointAndOnlyStartsRuns) {
  const std::string ckpt = temp_path("export_source.bin"), exported = temp_path("export.hnspolicy");
  TrainConfig cfg = tiny_quadrant();
  cfg.init_from = "/home/someone/runs/p8-s1/checkpoint.bin";  // as `hns train --init-from` records it
  Trainer source(cfg);
  source.iterate();
  source.iterate();
  source.save(ckpt);
  const uint64_t bytes = Trainer::export_policy(ckpt, exported);
  EXPECT_EQ(bytes, std::filesystem::file_size(exported));
  EXPECT_LT(double(bytes), 0.4 * double(std::filesystem::file_size(ckpt)));
  TrainConfig shared = Trainer::checkpoint_config(ckpt);
  EXPECT_EQ(shared.init_from, cfg.init_from);
  shared.init_from = "p8-s1/checkpoint.bin";
  EXPECT_EQ(Trainer::checkpoint_config(exported).to_json(), shared.to_json());

  // The same actions on the same observations, over whole episodes.
  const std::unique_ptr<Policy> from_ckpt = Policy::from_checkpoint(ckpt, 5);
  const std::unique_ptr<Policy> from_export = Policy::from_checkpoint(exported, 5);
  batch::BatchConfig bc = cfg.batch_config();
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

}  // namespace
}  // namespace hns::ppo
