// libFuzzer target: a training checkpoint as `hns train --resume` and `hns play --checkpoint` load it. An
// input that does not start with the checkpoint magic is also wrapped as the payload of a well-formed file
// (header and checksum right), so that mutated payloads reach the payload reader. Errors a user may see:
// std::runtime_error (a refused file) and physics::ConfigError (a bad config inside); anything else is a
// finding.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>

#include "physics/scene.hpp"
#include "ppo/trainer.hpp"

namespace {

// The checkpoint file layout of src/ppo/checkpoint.cpp: magic, version, payload length, payload, FNV-1a 64.
std::string wrap_as_checkpoint(const std::string& payload) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (const char c : payload) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ULL;
  }
  const uint32_t version = 1;
  const uint64_t length = payload.size();
  std::string file("HNSCKPT\n", 8);
  file.append(reinterpret_cast<const char*>(&version), sizeof version);
  file.append(reinterpret_cast<const char*>(&length), sizeof length);
  file += payload;
  file.append(reinterpret_cast<const char*>(&h), sizeof h);
  return file;
}

void load(hns::ppo::Trainer& trainer, const std::string& path, const std::string& bytes) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return;
  std::fwrite(bytes.data(), 1, bytes.size(), f);
  std::fclose(f);
  for (const auto mode : {hns::ppo::Trainer::LoadMode::kResume, hns::ppo::Trainer::LoadMode::kPolicy}) {
    try {
      trainer.load(path, mode);
    } catch (const std::runtime_error&) {
    } catch (const hns::physics::ConfigError&) {
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // One small trainer for every input (the lockbox task with the small model: what the seed corpus holds).
  static const std::unique_ptr<hns::ppo::Trainer> trainer = [] {
    hns::ppo::TrainConfig c;
    c.scene = "lockbox";
    c.model = "small";
    c.envs = 1;
    c.threads = 1;
    return std::make_unique<hns::ppo::Trainer>(c);
  }();
  static const std::string path = "/tmp/hns_fuzz_checkpoint_" + std::to_string(::getpid()) + ".bin";
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  load(*trainer, path, bytes);
  if (bytes.compare(0, 8, "HNSCKPT\n") != 0) load(*trainer, path, wrap_as_checkpoint(bytes));
  std::remove(path.c_str());
  return 0;
}
