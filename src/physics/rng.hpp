// Per-world random stream: xoshiro256** seeded through SplitMix64 from (seed, world index, episode).
// Counter-derived, so a world's stream depends only on those three numbers, never on thread timing.
#pragma once

#include <cstdint>

namespace hns::physics {

class Rng {
 public:
  Rng() : Rng(0, 0, 0) {}
  Rng(uint64_t seed, uint64_t world_index, uint64_t episode) {
    uint64_t x = splitmix(seed ^ 0x9E3779B97F4A7C15ULL);
    x = splitmix(x ^ world_index);
    x = splitmix(x ^ (episode * 0xD1B54A32D192ED03ULL));
    for (uint64_t& s : s_) s = splitmix(x);
  }

  uint64_t next_u64() {
    const uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }

  // Uniform integer in [lo, hi), like numpy's randint. Requires hi > lo.
  int uniform_int(int lo, int hi) {
    const uint64_t span = static_cast<uint64_t>(static_cast<int64_t>(hi) - lo);
    // Lemire's multiply-shift; the bias for spans this small (< 2^31) is below 2^-32.
    __extension__ using u128 = unsigned __int128;
    const uint64_t r = static_cast<uint64_t>((static_cast<u128>(next_u64()) * span) >> 64);
    return lo + static_cast<int>(r);
  }

  // Uniform double in [0, 1) with 53 random bits.
  double uniform01() { return static_cast<double>(next_u64() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform01(); }
  bool bernoulli(double p) { return uniform01() < p; }

 private:
  static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  static uint64_t splitmix(uint64_t& x) {
    uint64_t z = (x += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  static uint64_t splitmix(uint64_t&& x) { return splitmix(x); }

  uint64_t s_[4];
};

}  // namespace hns::physics
