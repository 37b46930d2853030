// Trainer checkpoints: a binary file of
//   magic "HNSCKPT\n" (8 bytes) | version u32 | payload length u64 | payload | FNV-1a 64 of the payload u64
// (little-endian, as the machines hns runs on). The payload holds the resolved config (JSON text), the
// counters, each env's next episode, the flat parameter buffer, Adam's moments and step, and both
// normalisers' state: everything the next iteration reads, so a resumed run is bit-identical.
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "ppo/atomic_file.hpp"
#include "ppo/trainer.hpp"

namespace hns::ppo {

namespace {

constexpr char kMagic[8] = {'H', 'N', 'S', 'C', 'K', 'P', 'T', '\n'};
constexpr uint32_t kVersion = 1;
constexpr size_t kHeaderBytes = 8 + 4 + 8;

uint64_t fnv1a64(const char* data, size_t n) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (size_t i = 0; i < n; ++i) {
    h ^= static_cast<unsigned char>(data[i]);
    h *= 0x100000001b3ULL;
  }
  return h;
}

class Writer {
 public:
  template <class T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    out_.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  template <class T>
  void put_array(const T* p, size_t n) {
    put(uint64_t(n));
    out_.append(reinterpret_cast<const char*>(p), n * sizeof(T));
  }
  void put_string(const std::string& s) { put_array(s.data(), s.size()); }
  std::string& bytes() { return out_; }

 private:
  std::string out_;
};

class Reader {
 public:
  Reader(const char* p, size_t n, const std::string& path) : p_(p), n_(n), path_(path) {}
  template <class T>
  T get() {
    T v;
    need(sizeof v);
    std::memcpy(&v, p_ + i_, sizeof v);
    i_ += sizeof v;
    return v;
  }
  // An array whose length must equal `expected` (what this run needs); `what` names it in the error.
  template <class T>
  void get_array(T* dst, size_t expected, const char* what) {
    const uint64_t n = get<uint64_t>();
    if (n != expected) {
      throw std::runtime_error("checkpoint " + path_ + ": " + what + " has " + std::to_string(n) +
                               " values, this run needs " + std::to_string(expected) +
                               " (a checkpoint of another model or scene?)");
    }
    need(n * sizeof(T));
    std::memcpy(dst, p_ + i_, n * sizeof(T));
    i_ += n * sizeof(T);
  }
  std::string get_string() {
    const uint64_t n = get<uint64_t>();
    need(n);
    std::string s(p_ + i_, n);
    i_ += n;
    return s;
  }
  bool at_end() const { return i_ == n_; }

 private:
  void need(uint64_t bytes) const {
    if (bytes > n_ - i_) throw std::runtime_error("checkpoint " + path_ + " is truncated inside its payload");
  }
  const char* p_;
  size_t n_;
  size_t i_ = 0;
  std::string path_;
};

// The payload of a checkpoint file after checking its magic, version, length and checksum.
std::string read_payload(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open checkpoint " + path);
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string file = ss.str();
  if (file.size() < kHeaderBytes + 8 || std::memcmp(file.data(), kMagic, sizeof kMagic) != 0) {
    throw std::runtime_error("checkpoint " + path + " is not an hns checkpoint (bad magic or too short)");
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

  return std::string(payload, length);
}

}  // namespace

void Trainer::save(const std::string& path) const {
  Writer w;
  w.put_string(cfg_.to_json());
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
    w.put_array(obs_norm_->biased_mean(key).data(), obs_norm_->biased_mean(key).size());
    w.put_array(obs_norm_->biased_sq(key).data(), obs_norm_->biased_sq(key).size());
    w.put(obs_norm_->debias(key));
  }
  w.put(value_norm_.biased_mean);
  w.put(value_norm_.biased_sq);
  w.put(value_norm_.debias);

  const std::string& payload = w.bytes();
  std::string file(kMagic, sizeof kMagic);
  const uint32_t version = kVersion;
  const uint64_t length = payload.size();
  const uint64_t sum = fnv1a64(payload.data(), payload.size());
  file.append(reinterpret_cast<const char*>(&version), sizeof version);
  file.append(reinterpret_cast<const char*>(&length), sizeof length);
  file += payload;
  file.append(reinterpret_cast<const char*>(&sum), sizeof sum);

  write_file_atomically(path, file);
}

TrainConfig Trainer::checkpoint_config(const std::string& path) {
  const std::string payload = read_payload(path);
  Reader r(payload.data(), payload.size(), path);
  TrainConfig c;
  c.merge_run_json(r.get_string(), path + " (config)");
  return c;
}

void Trainer::load(const std::string& path, LoadMode mode) {
  const std::string file = read_payload(path);
  const char* payload = file.data();
  const size_t length = file.size();
  Reader r(payload, length, path);
  TrainConfig saved = cfg_;
  saved.merge_run_json(r.get_string(), path + " (config)");
  std::string mismatch = saved.identity_mismatch(cfg_);
  if (mode == LoadMode::kPolicy) {
    // Only what shapes the networks must match.
    mismatch.clear();
    if (saved.model != cfg_.model)
      mismatch = "model: checkpoint has " + saved.model + ", this run has " + cfg_.model;
    if (saved.scene != cfg_.scene) {
      mismatch += std::string(mismatch.empty() ? "" : "; ") + "scene: checkpoint has " + saved.scene +
                  ", this run has " + cfg_.scene;
    }
  }
  if (!mismatch.empty()) {
    throw std::runtime_error("checkpoint " + path + " belongs to a run with another configuration (" +
                             mismatch + ")");
  }
  // Read into temporaries first: a refused checkpoint leaves the trainer untouched.
  const auto iteration = r.get<int64_t>();
  const auto agent_steps = r.get<int64_t>();
  const auto env_steps = r.get<int64_t>();
  const bool need_restart = r.get<uint8_t>() != 0;
  std::vector<int32_t> episodes(mode == LoadMode::kPolicy ? size_t(saved.envs) : next_episode_.size());
  r.get_array(episodes.data(), episodes.size(), "the env episode list");
  const size_t nf = net_->params().buffer_floats();
  nn::FloatBuffer values(nf), m(nf), v(nf);
  r.get_array(values.data(), nf, "the parameter buffer");
  r.get_array(m.data(), nf, "Adam's first moment");
  r.get_array(v.data(), nf, "Adam's second moment");
  const auto adam_steps = r.get<int64_t>();
  std::array<std::vector<double>, nn::kNumObsKeys> bm, bs;
  std::array<double, nn::kNumObsKeys> debias{};
  for (int k = 0; k < nn::kNumObsKeys; ++k) {
    const auto key = nn::ObsKey(k);
    bm[k].resize(obs_norm_->biased_mean(key).size());
    bs[k].resize(obs_norm_->biased_sq(key).size());
    r.get_array(bm[k].data(), bm[k].size(), "an observation normaliser");
    r.get_array(bs[k].data(), bs[k].size(), "an observation normaliser");
    debias[k] = r.get<double>();
  }
  ScalarNormalizer vn = value_norm_;
  vn.biased_mean = r.get<double>();
  vn.biased_sq = r.get<double>();
  vn.debias = r.get<double>();
  if (!r.at_end()) throw std::runtime_error("checkpoint " + path + " has unexpected bytes after its state");

  (void)need_restart;  // a fresh simulator always starts the saved episodes
  need_restart_ = true;
  iteration_ = iteration;
  agent_steps_ = agent_steps;
  env_steps_ = env_steps;
  if (mode == LoadMode::kResume) next_episode_ = std::move(episodes);
  std::memcpy(net_->params().values(), values.data(), nf * sizeof(float));
  std::memcpy(adam_->m().data(), m.data(), nf * sizeof(float));
  std::memcpy(adam_->v().data(), v.data(), nf * sizeof(float));
  adam_->set_steps(adam_steps);
  obs_norm_->set_state(bm, bs, debias);
  value_norm_ = vn;
}

}  // namespace hns::ppo
