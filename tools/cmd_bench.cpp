// `hns bench`: throughput of the batch simulator with seeded random actions.
//
//   hns bench --scene quadrant|full|empty [--envs N] [--steps S] [--threads T] [--seed S]
//             [--hiders H --seekers K --boxes B --ramps R] [--substeps N] [--json FILE] [--profile FILE]
//   hns bench --nn paper|small [--threads T] [--precision fp32|bf16|auto] [--json FILE]
#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "batch/batch_sim.hpp"
#include "batch/scenes.hpp"
#include "cli.hpp"
#include "nn/kernels.hpp"
#include "nn/nn_bench.hpp"
#include "nn/precision.hpp"
#include "ppo/batch_obs.hpp"

namespace hns::tools {
namespace {

using Clock = std::chrono::steady_clock;
namespace phys = hns::physics;

struct BenchOptions {
  std::string scene = "quadrant";
  int envs = 16;
  int steps = 1000;
  int threads = 1;
  std::string seed_text = "1";
  uint64_t seed = 1;  // parsed from seed_text
  std::optional<int> hiders, seekers, boxes, ramps, substeps;
  std::string json;
  std::string profile;
  std::string nn;                   // "paper" or "small": time the networks instead of the simulator
  std::string masks = "synthetic";  // --nn inputs: synthetic, or a scene's shape and mask densities
  std::string precision = "fp32";   // --nn: the networks' products (fp32 | bf16 | auto)
};

// Uniformly random bins for every action head.
void random_actions(phys::Rng& rng, std::vector<phys::AgentAction>& actions) {
  for (phys::AgentAction& a : actions) a = phys::random_action(rng);
}

constexpr int64_t kMaxProfileEvents = 4'000'000;  // about 400 MB of JSON: keep profiled runs short

// Throughput of the batch simulator with seeded uniformly random actions: env-steps/s, agent-steps/s and
// the thread time per phase.
int run_bench(const BenchOptions& opt) {
  hns::batch::BatchConfig config = batch::scene_config(opt.scene);
  batch::apply_overrides(config.world, batch::CountOverrides{opt.hiders, opt.seekers, opt.boxes, opt.ramps});
  if (opt.substeps) config.world.physics.substeps = *opt.substeps;
  config.num_envs = opt.envs;
  config.threads = usable_threads(opt.threads);
  config.seed = opt.seed;
  config.validate();
  check_memory("--envs " + std::to_string(opt.envs), config.estimated_bytes());
  if (!opt.json.empty()) check_output_path("--json", opt.json, {opt.profile});
  if (!opt.profile.empty()) check_output_path("--profile", opt.profile, {opt.json});

  const int64_t profile_events = int64_t(opt.envs) * opt.steps * 4;
  if (!opt.profile.empty() && profile_events > kMaxProfileEvents) {
    throw phys::ConfigError("profile = " + opt.profile + " with " + std::to_string(opt.envs) + " envs x " +
                            std::to_string(opt.steps) +
                            " steps is invalid: a profiled run may record at most " +
                            std::to_string(kMaxProfileEvents / 4) + " env-steps; use fewer --steps");
  }
  std::printf("hns bench: scene %s, %s x %s, %s, %s\n", opt.scene.c_str(),
              count_text(opt.envs, "env").c_str(), count_text(opt.steps, "step").c_str(),
              threads_text(opt.threads).c_str(),
              count_text(config.world.physics.substeps, "substep").c_str());
  std::fflush(stdout);
  hns::batch::BatchSim sim(config);
  sim.set_tracing(!opt.profile.empty());
  const int max_agents = sim.layout().max_agents;
  std::vector<phys::AgentAction> actions(size_t(opt.envs) * max_agents);
  phys::Rng rng(opt.seed, 0xAC7105, 0);
  sim.reset_timers();

  int64_t agent_steps = 0, episodes = 0;
  const auto start = Clock::now();
  auto last_report = start;
  for (int s = 0; s < opt.steps; ++s) {
    random_actions(rng, actions);
    for (int e = 0; e < opt.envs; ++e) agent_steps += sim.world(e).num_agents();
    sim.step(actions);
    episodes += int64_t(sim.finished().size());
    const auto now = Clock::now();
    if (now - last_report > std::chrono::seconds(2)) {
      last_report = now;
      const double done = double(s + 1) / opt.steps;
      const double elapsed = std::chrono::duration<double>(now - start).count();
      std::fprintf(stderr, "  step %d/%d (%.0f%%), %.0f env-steps/s, %lld unstable resets, ETA %.0f s\n",
                   s + 1, opt.steps, 100 * done, (s + 1.0) * opt.envs / elapsed,
                   static_cast<long long>(sim.unstable_resets()), elapsed * (1 - done) / done);
    }
  }
  const double wall = std::chrono::duration<double>(Clock::now() - start).count();
  const hns::batch::PhaseTimes& ph = sim.phase_times();
  const double thread_s = ph.total();
  const double env_steps = double(opt.envs) * opt.steps;
  auto share = [&](double x) { return thread_s > 0 ? 100 * x / thread_s : 0.0; };
  std::printf("  env-steps/s    %12.0f\n  agent-steps/s  %12.0f\n", env_steps / wall, agent_steps / wall);
  std::printf("  per env-step   %12.2f us of thread time, %lld episodes finished\n",
              1e6 * thread_s / env_steps, static_cast<long long>(episodes));
  std::printf(
      "  phases (share of thread time): physics %.1f%%, mirror %.1f%%, vision+lidar %.1f%%, "
      "observations %.1f%%, rewards/resets %.1f%%\n",
      share(ph.physics), share(ph.mirror), share(ph.perception), share(ph.observations), share(ph.rewards));
  // The soak figure (README, "Soak"): episodes reset after numerical trouble, per million env-steps.
  std::printf("  unstable resets %lld (%.3f per 10^6 env-steps)\n",
              static_cast<long long>(sim.unstable_resets()), 1e6 * double(sim.unstable_resets()) / env_steps);

  if (!opt.json.empty()) {
    nlohmann::json j = build_and_machine();
    j["scene"] = opt.scene;
    j["envs"] = opt.envs;
    j["threads"] = config.threads;
    j["steps"] = opt.steps;
    j["seed"] = opt.seed;
    j["substeps"] = config.world.physics.substeps;
    j["wall_s"] = wall;
    j["env_steps_per_s"] = env_steps / wall;
    j["agent_steps_per_s"] = agent_steps / wall;
    j["episodes_finished"] = episodes;
    j["unstable_resets"] = sim.unstable_resets();
    j["phases"] = {{"physics_s", ph.physics},
                   {"mirror_s", ph.mirror},
                   {"vision_lidar_s", ph.perception},
                   {"observations_s", ph.observations},
                   {"rewards_resets_s", ph.rewards}};
    write_atomically(opt.json, j.dump(2) + "\n");
    std::printf("  wrote %s\n", opt.json.c_str());
  }
  if (!opt.profile.empty()) {
    write_chrome_trace(opt.profile, sim.take_trace());
    std::printf("  wrote %s (open it in chrome://tracing or ui.perfetto.dev)\n", opt.profile.c_str());
  }
  return 0;
}

// The observation shape of `scene` and the density of its masks over 16 envs x 2 episodes of uniformly
// random actions (what the networks see at the start of training): per entity type, how often a slot holds
// an entity and how often a present entity is seen, over the agents that exist.
void measure_scene_masks(const std::string& scene, uint64_t seed, hns::nn::NnBenchOptions& o) {
  namespace hb = hns::batch;
  hb::BatchConfig config = hb::scene_config(scene);
  config.num_envs = 16;
  config.threads = o.threads;
  config.seed = seed;
  hb::BatchSim sim(config);
  const hb::Layout& L = sim.layout();
  o.shape = hns::ppo::obs_shape(L);
  std::vector<phys::AgentAction> actions(size_t(config.num_envs) * L.max_agents);
  phys::Rng rng(seed, 0xAC7105, 1);
  double slots[3] = {}, present[3] = {}, seen[3] = {};
  const hb::BatchState& st = sim.state();
  for (int step = 0; step < 2 * config.world.horizon; ++step) {
    random_actions(rng, actions);
    sim.step(actions);
    for (int e = 0; e < config.num_envs; ++e)
      for (int a = 0; a < L.max_agents; ++a) {
        const size_t row = size_t(e) * L.max_agents + a;
        if (st.agent_exists.data()[row] == 0) continue;
        auto count = [&](int type, const uint8_t* value_mask, const uint8_t* policy_mask, int n) {
          for (int j = 0; j < n; ++j) {
            slots[type] += 1;
            present[type] += value_mask[row * n + j];
            seen[type] += policy_mask[row * n + j];
          }
        };
        count(0, st.value_mask_agents.data(), st.mask_agents.data(), L.others);
        count(1, st.value_mask_boxes.data(), st.mask_boxes.data(), L.max_boxes);
        count(2, st.value_mask_ramps.data(), st.mask_ramps.data(), L.max_ramps);
      }
  }
  auto ratio = [](double a, double b) { return b > 0 ? a / b : 0.0; };
  hns::nn::MaskDensity& d = o.masks;
  d.name = scene;
  d.alternate_last_box = false;
  d.agents_present = ratio(present[0], slots[0]), d.agents_seen = ratio(seen[0], present[0]);
  d.boxes_present = ratio(present[1], slots[1]), d.boxes_seen = ratio(seen[1], present[1]);
  d.ramps_present = ratio(present[2], slots[2]), d.ramps_seen = ratio(seen[2], present[2]);
}

// Throughput of the policy + value networks (`--nn MODEL`) on synthetic observations: full-scene shaped with
// 60 % of entities seen, or shaped and masked like `--masks SCENE`.
int run_nn_bench(const BenchOptions& opt) {
  hns::nn::NnBenchOptions o;
  o.model = opt.nn;
  o.threads = usable_threads(opt.threads);
  o.seed = opt.seed;
  try {
    o.precision = hns::nn::resolve_precision(opt.precision);
  } catch (const std::invalid_argument& e) {
    throw phys::ConfigError(std::string("--precision: ") + e.what());
  }
  if (opt.masks != "synthetic") measure_scene_masks(opt.masks, opt.seed, o);
  if (!opt.json.empty()) check_output_path("--json", opt.json);
  int chunk = 0;  // the training chunk the trainer would use for this model
  try {
    chunk = hns::nn::default_train_chunk(hns::nn::net_preset(opt.nn));
  } catch (const std::invalid_argument& e) {
    throw phys::ConfigError(std::string("--nn: ") + e.what());
  }
  std::printf("hns bench --nn %s: %s (inference: %d agents x 1 step; ", opt.nn.c_str(),
              threads_text(opt.threads).c_str(), o.infer_agents);
  std::printf("training: %d sequences x %d steps, in chunks of %d sequences)\n", o.train_sequences,
              o.train_steps, chunk);
  std::printf("  instruction set         %s\n", hns::nn::kernels::isa_description().c_str());
  std::printf("  precision               %s\n", hns::nn::precision_description(o.precision).c_str());
  const hns::nn::MaskDensity& d = o.masks;
  std::printf(
      "  inputs                  %s: %d other agents, %d boxes, %d ramps; present %.0f/%.0f/%.0f %%, seen "
      "%.0f/%.0f/%.0f %% of present\n",
      d.name.c_str(), o.shape.num_other_agents(), o.shape.max_boxes, o.shape.max_ramps,
      100 * d.agents_present, 100 * d.boxes_present, 100 * d.ramps_present, 100 * d.agents_seen,
      100 * d.boxes_seen, 100 * d.ramps_seen);
  std::fflush(stdout);
  const hns::nn::NnBenchResult r = hns::nn::run_nn_bench(o);
  // Rates as a share of the GEMM reference of the precision that ran (bf16: the bf16 kernel's GEMM).
  const bool bf16 = o.precision == hns::nn::Precision::kBf16;
  const double reference = bf16 ? r.gemm_bf16_gflops : r.gemm_gflops;
  const char* gemm = bf16 ? "bf16 GEMM" : "GEMM";
  std::printf("  parameters              %12zu (policy + value)\n", r.params);
  std::printf("  inference agent-steps/s %12.0f  %7.1f GFLOP/s (%.0f%% of %s), useful %.1f GFLOP/s\n",
              r.infer_agent_steps_per_s, r.infer_gflops, 100 * r.infer_gflops / reference, gemm,
              r.infer_useful_gflops);
  std::printf("  training agent-steps/s  %12.0f  %7.1f GFLOP/s (%.0f%% of %s), useful %.1f GFLOP/s\n",
              r.train_agent_steps_per_s, r.train_gflops, 100 * r.train_gflops / reference, gemm,
              r.train_useful_gflops);
  std::printf("  Eigen GEMM reference                  %7.1f GFLOP/s\n", r.gemm_gflops);
  if (bf16) std::printf("  bf16 GEMM reference                   %7.1f GFLOP/s\n", r.gemm_bf16_gflops);
  if (!opt.json.empty()) {
    nlohmann::json j = {{"model", r.model},
                        {"threads", r.threads},
                        {"params", r.params},
                        {"isa", hns::nn::kernels::isa_description()},
                        {"precision", r.precision},
                        {"precision_description", r.precision_description},
                        {"infer_agent_steps_per_s", r.infer_agent_steps_per_s},
                        {"train_agent_steps_per_s", r.train_agent_steps_per_s},
                        {"infer_gflops", r.infer_gflops},
                        {"train_gflops", r.train_gflops},
                        {"infer_useful_gflops", r.infer_useful_gflops},
                        {"train_useful_gflops", r.train_useful_gflops},
                        {"masks", r.masks},
                        {"gemm_gflops", r.gemm_gflops},
                        {"infer_seconds", r.infer_seconds},
                        {"train_seconds", r.train_seconds}};
    if (bf16) j["gemm_bf16_gflops"] = r.gemm_bf16_gflops;
    j.update(build_and_machine());
    write_atomically(opt.json, j.dump(2) + "\n");
    std::printf("  wrote %s\n", opt.json.c_str());
  }
  return 0;
}

}  // namespace

void add_bench_command(CLI::App& app, std::vector<Command>& commands) {
  auto opt = std::make_shared<BenchOptions>();
  CLI::App* cmd = app.add_subcommand("bench", "Throughput of the simulator with random actions");
  cmd->add_option("--scene", opt->scene, "Scene (the list below)")
      ->check(CLI::IsMember(batch::scene_names()))
      ->capture_default_str();
  cmd->footer(scene_help());
  cmd->add_option("--envs", opt->envs, "Number of envs")
      ->check(CLI::Range(1, 1 << 20))
      ->capture_default_str();
  cmd->add_option("--steps", opt->steps, "Env steps per env")
      ->check(CLI::Range(1, 1 << 30))
      ->capture_default_str();
  cmd->add_option("--threads", opt->threads, "Worker threads (0 = all the machine has)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  cmd->add_option("--seed", opt->seed_text, "Seed of scenes and actions, 0 .. 2^64 - 1")
      ->capture_default_str();
  cmd->add_option("--hiders", opt->hiders, "Fix the hider count")->check(CLI::Range(0, 32));
  cmd->add_option("--seekers", opt->seekers, "Fix the seeker count")->check(CLI::Range(0, 32));
  cmd->add_option("--boxes", opt->boxes, "Fix the box count")->check(CLI::Range(0, 32));
  cmd->add_option("--ramps", opt->ramps, "Fix the ramp count")->check(CLI::Range(0, 16));
  cmd->add_option("--substeps", opt->substeps, "Physics substeps per env step")->check(CLI::Range(1, 200));
  cmd->add_option("--json", opt->json, "Write the figures as JSON to this file");
  cmd->add_option("--profile", opt->profile,
                  "Write a per-phase Chrome trace (JSON) of a short run to this file");
  cmd->add_option("--nn", opt->nn, "Time the policy + value networks of this model instead of the simulator")
      ->check(CLI::IsMember({"paper", "small"}));
  cmd->add_option(
         "--masks", opt->masks,
         "With --nn: synthetic inputs (full-scene shape, 60 % seen), or the shape and mask density of "
         "random-action episodes of this scene")
      ->check(CLI::IsMember({"synthetic", "quadrant", "full"}))
      ->capture_default_str();
  cmd->add_option("--precision", opt->precision,
                  "With --nn: the networks' matrix products: fp32, bf16 (bf16 operands, float sums; needs "
                  "AVX512-BF16) or auto (bf16 where the CPU has it)")
      ->check(CLI::IsMember({"fp32", "bf16", "auto"}))
      ->capture_default_str();
  commands.push_back({cmd, [opt, cmd] {
                        opt->seed = parse_seed("--seed", opt->seed_text);
                        if (opt->nn.empty() && cmd->count("--masks") > 0)
                          throw phys::ConfigError(
                              "--masks " + opt->masks +
                              " is invalid without --nn (it chooses the network's inputs)");
                        if (opt->nn.empty() && cmd->count("--precision") > 0)
                          throw phys::ConfigError("--precision " + opt->precision +
                                                  " is invalid without --nn (it chooses the networks' "
                                                  "products)");
                        return opt->nn.empty() ? run_bench(*opt) : run_nn_bench(*opt);
                      }});
}

}  // namespace hns::tools
