// Trainer checkpoints: a binary file of
//   magic "HNSCKPT\n" (8 bytes) | version u32 | payload length u64 | payload | FNV-1a 64 of the payload u64
// (little-endian, as the machines hns runs on). The payload holds the resolved config (JSON text), the
// counters, each env's next episode, the flat parameter buffer, Adam's moments and step, and both
// normalisers' state: everything the next iteration reads, so a resumed run is bit-identical.
// Exported policies have the same frame with magic "HNSPLCY\n" and a payload of the config, the counters,
// the parameter buffer and the normalisers (the checkpoint's without the episode list, the optimiser and
// the exploration state).
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "ppo/atomic_file.hpp"
#include "ppo/batch_obs.hpp"
#include "ppo/checkpoint_io.hpp"
#include "ppo/trainer.hpp"

namespace hns::ppo {

namespace {

constexpr char kMagic[8] = {'H', 'N', 'S', 'C', 'K', 'P', 'T', '\n'};
constexpr char kPolicyMagic[8] = {'H', 'N', 'S', 'P', 'L', 'C', 'Y', '\n'};
constexpr uint32_t kVersion = 1;
constexpr size_t kHeaderBytes = 8 + 4 + 8;

struct Payload {
  std::string bytes;
  bool exported = false;  // an exported policy (kPolicyMagic), not a checkpoint
};

// The payload of a checkpoint or exported policy file after checking its magic, version, length and checksum.
Payload read_payload(const std::string& path) {
  const std::string file = read_regular_file(path, kMaxCheckpointBytes, "checkpoint");
  const bool exported =
      file.size() >= sizeof kPolicyMagic && std::memcmp(file.data(), kPolicyMagic, sizeof kPolicyMagic) == 0;
  if (file.size() < kHeaderBytes + 8 || (!exported && std::memcmp(file.data(), kMagic, sizeof kMagic) != 0)) {
    throw std::runtime_error("checkpoint " + path +
                             " is not an hns checkpoint or exported policy (bad magic or too short)");
  }
  uint32_t version = 0;
  uint64_t length = 0;
  std::memcpy(&version, file.data() + 8, sizeof version);
  std::memcpy(&length, file.data() + 12, sizeof length);
  if (version != kVersion) {
    throw std::runtime_error("checkpoint " + path + " has format version " + std::to_string(version) +
                             ", this hns reads version " + std::to_string(kVersion));
  }
  if (length != file.size() - kHeaderBytes - 8) {
    throw std::runtime_error("checkpoint " + path + " is truncated or padded: header says " +
                             std::to_string(length) + " payload bytes, the file holds " +
                             std::to_string(file.size() - kHeaderBytes - 8));
  }
  const char* payload = file.data() + kHeaderBytes;
  uint64_t stored = 0;
  std::memcpy(&stored, payload + length, sizeof stored);
  if (fnv1a64(payload, length) != stored) {
    throw std::runtime_error("checkpoint " + path + " is corrupt: checksum mismatch");
  }

  return {std::string(payload, length), exported};
}

// The file frame around a payload: magic, version, length, payload, checksum.
std::string framed(const char (&magic)[8], const std::string& payload) {
  std::string file(magic, sizeof magic);
  const uint32_t version = kVersion;
  const uint64_t length = payload.size();
  const uint64_t sum = fnv1a64(payload.data(), payload.size());
  file.append(reinterpret_cast<const char*>(&version), sizeof version);
  file.append(reinterpret_cast<const char*>(&length), sizeof length);
  file += payload;
  file.append(reinterpret_cast<const char*>(&sum), sizeof sum);
  return file;
}

}  // namespace

std::string Trainer::checkpoint_payload() const {
  CheckpointWriter w;
  // The thread count is the machine's, not the run's (results do not depend on it): recorded as 0, so that a
  // checkpoint is the same bytes for any thread count, as for any rank count.
  TrainConfig stored = cfg_;
  stored.threads = 0;
  w.put_string(stored.to_json());
  w.put(iteration_);
  w.put(agent_steps_);
  w.put(env_steps_);
  w.put(uint8_t(need_restart_ ? 1 : 0));
  w.put_array(next_episode_.data(), next_episode_.size());
  const size_t nf = net_->params().buffer_floats();
  w.put_array(net_->params().values(), nf);
  w.put_array(adam_->m().data(), nf);
  w.put_array(adam_->v().data(), nf);
  w.put(adam_->steps());
  for (int k = 0; k < nn::kNumObsKeys; ++k) {
    const auto key = nn::ObsKey(k);
    if (key == nn::kObsSites && obs_norm_->features(key) == 0) continue;  // written only where sites exist
    w.put_array(obs_norm_->biased_mean(key).data(), obs_norm_->biased_mean(key).size());
    w.put_array(obs_norm_->biased_sq(key).data(), obs_norm_->biased_sq(key).size());
    w.put(obs_norm_->debias(key));
  }
  w.put(value_norm_.biased_mean);
  w.put(value_norm_.biased_sq);
  w.put(value_norm_.debias);
  // The exploration bonus's own section (intrinsic_reward.hpp; nothing for none).
  intrinsic_->save(w);

  return w.bytes();
}

uint64_t Trainer::fingerprint() const {
  const std::string payload = checkpoint_payload();
  return fnv1a64(payload.data(), payload.size());
}

void Trainer::save(const std::string& path) const {
  write_file_atomically(path, framed(kMagic, checkpoint_payload()));
}

namespace {
// The config a checkpoint holds, over `base`, checked as a run's config is: a checkpoint with an unknown key
// or an invalid value is a bad checkpoint (std::runtime_error), not a bad command line.
TrainConfig stored_config(CheckpointReader& r, const TrainConfig& base, const std::string& path) {
  TrainConfig c = base;
  try {
    c.merge_run_json(r.get_string(), path + " (config)");
    c.validate();
  } catch (const physics::ConfigError& e) {
    throw std::runtime_error("checkpoint " + path + " holds an invalid config: " + e.what());
  }
  return c;
}
}  // namespace

TrainConfig Trainer::checkpoint_config(const std::string& path) {
  const std::string payload = read_payload(path).bytes;
  CheckpointReader r(payload.data(), payload.size(), path);
  return stored_config(r, TrainConfig(), path);
}

// Everything a checkpoint holds, read and checked before any of it is applied (a refused checkpoint leaves
// the trainer untouched).
struct Trainer::CheckpointState {
  TrainConfig config;
  int64_t iteration = 0, agent_steps = 0, env_steps = 0;
  std::vector<int32_t> episodes;  // per env of the saved run
  nn::FloatBuffer values, m, v;
  int64_t adam_steps = 0;
  std::array<std::vector<double>, nn::kNumObsKeys> obs_mean, obs_sq;
  std::array<double, nn::kNumObsKeys> obs_debias{};
  nn::ParamLayout layout;  // the saved run's parameter layout (values, m, v are in it)
  nn::ObsShape shape;      // the saved run's observation shape
  ScalarNormalizer value_norm;
  std::unique_ptr<IntrinsicState> intrinsic;  // the exploration bonus's state (null in an exported policy)
  bool exported = false;  // an exported policy: no episodes, optimiser or exploration state (zeros here)
};

Trainer::CheckpointState Trainer::read_checkpoint(
    const std::string& path, const std::function<std::string(const TrainConfig&)>& mismatch,
    bool to_resume) const {
  const Payload payload = read_payload(path);
  if (payload.exported && to_resume) {
    throw std::runtime_error("checkpoint " + path +
                             " is an exported policy (weights and normalisers, no optimiser state or episode "
                             "list): it can act (hns play --checkpoint, Policy.load) and start a new run "
                             "(--init-from), not resume one");
  }
  const std::string& file = payload.bytes;
  CheckpointReader r(file.data(), file.size(), path);
  CheckpointState st;
  st.exported = payload.exported;
  st.config = stored_config(r, cfg_, path);
  // The caller's refusal first; then the arrays, whose sizes are this trainer's (the model decides them).
  std::string why = mismatch(st.config);
  if (why.empty() && st.config.model != cfg_.model) {
    why = "model: checkpoint has " + st.config.model + ", this run has " + cfg_.model;
  }
  if (!why.empty()) {
    throw std::runtime_error("checkpoint " + path + " belongs to a run with another configuration (" + why +
                             ")");
  }
  const TrainConfig& saved = st.config;
  // The saved run's shapes: its scene decides them (the same as this run's, except in initialize_from).
  nn::NetConfig saved_net = net_->config();
  {
    batch::BatchConfig bc = saved.batch_config();
    saved_net.obs = obs_shape(batch::Layout::of(bc));
  }
  st.shape = saved_net.obs;
  st.layout = nn::ActorCritic::layout_of(saved_net);
  const nn::ObsNormalizer saved_norm(saved_net.obs);
  st.iteration = r.get<int64_t>();
  st.agent_steps = r.get<int64_t>();
  st.env_steps = r.get<int64_t>();
  const size_t nf = st.layout.buffer_floats();
  st.values.resize(nf);
  st.m.resize(nf);  // zeros in an exported policy
  st.v.resize(nf);
  if (st.exported) {
    r.get_array(st.values.data(), nf, "the parameter buffer");
  } else {
    (void)r.get<uint8_t>();  // need_restart: a fresh simulator always starts the saved episodes
    st.episodes.resize(size_t(saved.envs));
    r.get_array(st.episodes.data(), st.episodes.size(), "the env episode list");
    r.get_array(st.values.data(), nf, "the parameter buffer");
    r.get_array(st.m.data(), nf, "Adam's first moment");
    r.get_array(st.v.data(), nf, "Adam's second moment");
    st.adam_steps = r.get<int64_t>();
  }
  for (int k = 0; k < nn::kNumObsKeys; ++k) {
    const auto key = nn::ObsKey(k);
    if (key == nn::kObsSites && saved_norm.features(key) == 0) continue;  // a scene without sites
    st.obs_mean[k].resize(saved_norm.biased_mean(key).size());
    st.obs_sq[k].resize(saved_norm.biased_sq(key).size());
    r.get_array(st.obs_mean[k].data(), st.obs_mean[k].size(), "an observation normaliser");
    r.get_array(st.obs_sq[k].data(), st.obs_sq[k].size(), "an observation normaliser");
    st.obs_debias[k] = r.get<double>();
  }
  st.value_norm = value_norm_;
  st.value_norm.biased_mean = r.get<double>();
  st.value_norm.biased_sq = r.get<double>();
  st.value_norm.debias = r.get<double>();
  if (!st.exported) st.intrinsic = read_intrinsic_state(r, saved, saved_net);
  if (!r.at_end()) throw std::runtime_error("checkpoint " + path + " has unexpected bytes after its state");
  check_values(st, path);
  return st;
}

// Values a checksum cannot vouch for (a file written by a broken tool, or edited and re-summed): what no
// training run can produce is refused before any of it is applied, as a config's values are.
void Trainer::check_values(const CheckpointState& st, const std::string& path) {
  const auto refuse = [&](const std::string& what) {
    throw std::runtime_error("checkpoint " + path + " holds an impossible state: " + what);
  };
  const auto counter = [&](const char* name, int64_t v) {
    if (v < 0) refuse(std::string(name) + " is " + std::to_string(v) + " (a count is at least 0)");
  };
  counter("the iteration", st.iteration);
  counter("the agent-step count", st.agent_steps);
  counter("the env-step count", st.env_steps);
  counter("Adam's step count", st.adam_steps);
  for (size_t e = 0; e < st.episodes.size(); ++e) {
    if (st.episodes[e] < 0) refuse("env " + std::to_string(e) + "'s episode count is negative");
    // The counter is an int32 that the run keeps counting up: no run comes near 2^30 episodes per env, and
    // one resumed from there could overflow it in the checkpoint it writes.
    if (st.episodes[e] > (1 << 30)) {
      refuse("env " + std::to_string(e) + "'s episode count is " + std::to_string(st.episodes[e]) +
             " (at most 2^30)");
    }
  }
  const auto floats = [&](const char* name, const auto& values, bool non_negative) {
    refuse_bad_values<std::decay_t<decltype(values[0])>>(refuse, name, values.data(), values.size(),
                                                         non_negative);
  };
  floats("the parameter buffer", st.values, false);
  floats("Adam's first moment", st.m, false);
  floats("Adam's second moment", st.v, true);
  if (st.intrinsic) st.intrinsic->check(refuse);
  for (int k = 0; k < nn::kNumObsKeys; ++k) {
    floats("an observation normaliser's mean", st.obs_mean[k], false);
    floats("an observation normaliser's mean square", st.obs_sq[k], true);
  }
  const std::array<double, 3> value_norm = {st.value_norm.biased_mean, st.value_norm.biased_sq,
                                            st.value_norm.debias};
  floats("the value normaliser", value_norm, false);
  floats("the observation normalisers' debias terms", st.obs_debias, true);
  if (st.value_norm.biased_sq < 0 || st.value_norm.debias < 0)
    refuse("the value normaliser has a negative square or weight");
}

void Trainer::load(const std::string& path, LoadMode mode) {
  CheckpointState st = read_checkpoint(
      path,
      [&](const TrainConfig& saved) -> std::string {
        // kResume: every results-affecting key; kPolicy: only what shapes the networks (model, then scene).
        if (mode == LoadMode::kResume) return saved.identity_mismatch(cfg_);
        std::string why;
        if (saved.model != cfg_.model)
          why = "model: checkpoint has " + saved.model + ", this run has " + cfg_.model;
        if (saved.scene != cfg_.scene) {
          why += std::string(why.empty() ? "" : "; ") + "scene: checkpoint has " + saved.scene +
                 ", this run has " + cfg_.scene;
        }
        return why;
      },
      mode == LoadMode::kResume);
  need_restart_ = true;
  iteration_ = st.iteration;
  agent_steps_ = st.agent_steps;
  env_steps_ = st.env_steps;
  if (mode == LoadMode::kResume) next_episode_ = std::move(st.episodes);
  const size_t nf = net_->params().buffer_floats();
  if (st.values.size() != nf) throw std::logic_error("Trainer::load: a checkpoint of another layout");
  std::memcpy(net_->params().values(), st.values.data(), nf * sizeof(float));
  std::memcpy(adam_->m().data(), st.m.data(), nf * sizeof(float));
  std::memcpy(adam_->v().data(), st.v.data(), nf * sizeof(float));
  adam_->set_steps(st.adam_steps);
  obs_norm_->set_state(st.obs_mean, st.obs_sq, st.obs_debias);
  value_norm_ = st.value_norm;
  if (mode == LoadMode::kResume && st.intrinsic) intrinsic_->restore(*st.intrinsic);
}

namespace {
// A slice of a network's head: "<net>/out_norm/...", "policy/logits/..." or "value/value/..." (EntityNet).
bool is_head_slice(const std::string& name) {
  const size_t slash = name.find('/');
  if (slash == std::string::npos) return false;
  const std::string_view rest = std::string_view(name).substr(slash + 1);
  return rest.rfind("out_norm/", 0) == 0 || rest.rfind("logits/", 0) == 0 || rest.rfind("value/", 0) == 0;
}
}  // namespace

std::string Trainer::initialize_from(const std::string& path) {
  if (iteration_ != 0) throw std::logic_error("Trainer::initialize_from: the run has already started");
  const nn::ObsShape& mine = net_->config().obs;
  CheckpointState st = read_checkpoint(path, [&](const TrainConfig& saved) -> std::string {
    if (saved.model != cfg_.model)
      return "model: checkpoint has " + saved.model + ", this run has " + cfg_.model;
    batch::BatchConfig bc = saved.batch_config();
    const nn::ObsShape theirs = obs_shape(batch::Layout::of(bc));
    // The weights depend on which entity types a scene has, not on their slot counts (the embeddings are
    // shared by the slots of a type and pooled): a hide-and-seek policy acts in a transfer task with more or
    // fewer boxes. This run may add the site type (blueprint from hide-and-seek): its embedding starts from
    // the seed, as in the paper.
    auto types = [](const nn::ObsShape& o) {
      return std::to_string(o.max_agents - 1) + " other agents, " + std::to_string(o.max_boxes) + " boxes, " +
             std::to_string(o.max_ramps) + " ramps, " + std::to_string(o.max_sites) + " sites";
    };
    const bool sites_ok =
        theirs.max_sites == 0 || (mine.max_sites > 0 && theirs.site_features == mine.site_features);
    if ((theirs.max_agents > 1) != (mine.max_agents > 1) || (theirs.max_boxes > 0) != (mine.max_boxes > 0) ||
        (theirs.max_ramps > 0) != (mine.max_ramps > 0) || !sites_ok) {
      return "observation slots: the checkpoint's scene " + saved.scene + " has " + types(theirs) +
             ", this run's " + cfg_.scene + " " + types(mine) +
             "; the entity types present (other agents, boxes, ramps) must be the same (sites may be added)";
    }
    if (cfg_.init_optimizer != 0 && theirs.max_sites == 0 && mine.max_sites > 0) {
      return "init_optimizer = 1: the checkpoint lacks this run's site embeddings, and Adam's step count "
             "would skip their zero moments' bias correction; use init_optimizer = 0";
    }
    return "";
  });
  if (cfg_.init_optimizer != 0 && st.exported) {
    throw std::runtime_error("--init-from " + path +
                             ": init_optimizer = 1 needs Adam's moments, and an exported policy has none; "
                             "use the run's checkpoint.bin or init_optimizer = 0");
  }
  // The policy's slices always; the value net's (with its return normaliser) when init_value is set; each
  // network's head (its final layer norm and output layer) unless init_heads is 0. Slices are matched by
  // name: one the checkpoint lacks (a site embedding) keeps its initialisation from the seed.
  std::string carried = cfg_.init_heads != 0 ? "policy weights" : "policy weights (heads from the seed)";
  const nn::ParamLayout& layout = net_->params().layout();
  float* values = net_->params().values();
  int fresh = 0;
  for (const nn::ParamSlice& slice : layout.slices()) {
    const bool value_net = slice.name.rfind("value/", 0) == 0;
    if (value_net && cfg_.init_value == 0) continue;
    if (cfg_.init_heads == 0 && is_head_slice(slice.name)) continue;
    const nn::ParamSlice* from = st.layout.find(slice.name);
    if (from == nullptr) {
      ++fresh;
      continue;
    }
    if (from->rows != slice.rows || from->cols != slice.cols)
      throw std::logic_error("Trainer::initialize_from: slice " + slice.name + " has another shape");
    std::memcpy(values + slice.offset, st.values.data() + from->offset, slice.size() * sizeof(float));
  }
  if (fresh > 0) carried += " (" + std::to_string(fresh) + " slices the checkpoint lacks from the seed)";
  if (cfg_.init_value != 0) {
    carried += ", value weights";
    if (cfg_.init_normalizers != 0) value_norm_ = st.value_norm;
  }
  if (cfg_.init_normalizers != 0) {
    // Keys the checkpoint lacks (sites) keep their fresh statistics.
    for (int k = 0; k < nn::kNumObsKeys; ++k) {
      const auto key = nn::ObsKey(k);
      if (st.obs_mean[k].size() == obs_norm_->biased_mean(key).size()) continue;
      st.obs_mean[k] = obs_norm_->biased_mean(key);
      st.obs_sq[k] = obs_norm_->biased_sq(key);
      st.obs_debias[k] = obs_norm_->debias(key);
    }
    obs_norm_->set_state(st.obs_mean, st.obs_sq, st.obs_debias);
    carried += cfg_.init_value != 0 ? ", observation and return normalisers" : ", observation normaliser";
  }
  if (cfg_.init_optimizer != 0) {  // validate() makes sure both networks were carried
    for (const nn::ParamSlice& slice : layout.slices()) {
      const nn::ParamSlice* from = st.layout.find(slice.name);
      if (from == nullptr) continue;
      std::memcpy(adam_->m().data() + slice.offset, st.m.data() + from->offset, slice.size() * sizeof(float));
      std::memcpy(adam_->v().data() + slice.offset, st.v.data() + from->offset, slice.size() * sizeof(float));
    }
    adam_->set_steps(st.adam_steps);
    carried += ", Adam's moments and step count";
  }
  return carried + " of a " + st.config.scene + " run at iteration " + std::to_string(st.iteration);
}

uint64_t Trainer::export_policy(const std::string& checkpoint, const std::string& out) {
  // A trainer of the checkpoint's model and scene only to read and check the file (one env, one thread,
  // float products: nothing runs).
  TrainConfig cfg = checkpoint_config(checkpoint);
  cfg.envs = 1;
  cfg.threads = 1;
  cfg.minibatches = 1;
  cfg.minibatch_chunks = 0;  // the run's may not fit one env
  cfg.precision = "fp32";
  const Trainer reader(cfg);
  const CheckpointState st = reader.read_checkpoint(checkpoint, [](const TrainConfig&) { return ""; });
  if (st.exported) throw std::runtime_error(checkpoint + " is already an exported policy");
  // An export is made to be shared: the file its run started from is named by its folder and file name only
  // (p8-s1/checkpoint.bin, models/x.hnspolicy), not by a directory of the machine that trained it.
  TrainConfig shared = st.config;
  if (!shared.init_from.empty()) {
    const std::filesystem::path from(shared.init_from);
    shared.init_from = (from.parent_path().filename() / from.filename()).generic_string();
  }
  CheckpointWriter w;
  w.put_string(shared.to_json());
  w.put(st.iteration);
  w.put(st.agent_steps);
  w.put(st.env_steps);
  w.put_array(st.values.data(), st.values.size());
  for (int k = 0; k < nn::kNumObsKeys; ++k) {
    const auto key = nn::ObsKey(k);
    if (key == nn::kObsSites && st.obs_mean[k].empty()) continue;  // as in the checkpoint
    w.put_array(st.obs_mean[k].data(), st.obs_mean[k].size());
    w.put_array(st.obs_sq[k].data(), st.obs_sq[k].size());
    w.put(st.obs_debias[k]);
  }
  w.put(st.value_norm.biased_mean);
  w.put(st.value_norm.biased_sq);
  w.put(st.value_norm.debias);
  const std::string file = framed(kPolicyMagic, w.bytes());
  write_file_atomically(out, file);
  return file.size();
}

}  // namespace hns::ppo
