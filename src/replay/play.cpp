#include "replay/play.hpp"

namespace hns::replay {

RecordConfig play_config(const std::string& scene, const ppo::Policy* policy,
                         const batch::CountOverrides& counts, int episodes, int envs, int threads,
                         uint64_t seed) {
  RecordConfig config;
  config.scene = scene.empty() ? "quadrant" : scene;
  config.game = batch::scene_config(config.scene);
  if (policy != nullptr) {
    if (!scene.empty() && scene != policy->config().scene) {
      throw physics::ConfigError("scene = " + scene + ": the checkpoint was trained on scene '" +
                                 policy->config().scene + "' (leave the scene out to use it)");
    }
    config.scene = policy->config().scene;
    config.game = policy->config().batch_config();
  }
  batch::apply_overrides(config.game.world, counts);
  config.episodes = episodes;
  // More envs than episodes would only play episodes nobody records.
  config.game.num_envs = std::min(envs, episodes);
  config.game.threads = threads;
  config.game.seed = seed;
  config.game.validate();
  return config;
}

ActionFn play_actions(ppo::Policy* policy, uint64_t seed) {
  if (policy == nullptr) return RandomActions(seed);
  return [policy](const batch::BatchSim& sim, std::span<physics::AgentAction> actions) {
    policy->act(sim, actions);
  };
}

}  // namespace hns::replay
