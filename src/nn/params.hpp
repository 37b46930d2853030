// Parameters and gradients live in flat contiguous float buffers (one for all values, one for all gradients),
// so the optimiser, checkpoints and a future all-reduce see a single array. Layers register named slices in a
// ParamLayout at construction and keep only offsets; forward/backward receive the buffers' base pointers.
#pragma once

#include "nn/tensor.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace hns::nn {

// How a slice is initialised (docs/game.md §10.2).
enum class Init : uint8_t {
  kZeros,
  kOnes,
  kXavierUniform,  // U(-a, a), a = sqrt(6 / (fan_in + fan_out))
  kNormal,         // N(0, std)
  kNormc,          // per output column: N(0, 1) rescaled to L2 norm `std` (baselines normc_initializer)
};

struct ParamSlice {
  std::string name;   // e.g. "policy/sa/qk/w"
  size_t offset = 0;  // into the flat buffers, floats (64-byte aligned)
  int rows = 0;       // [rows, cols] row-major; biases and gains are [1, cols]
  int cols = 0;
  bool decay = false;  // weight decay applies (kernels, not biases or norm gains)
  Init init = Init::kZeros;
  float fan_in = 0.0f;   // for kXavierUniform
  float fan_out = 0.0f;  // for kXavierUniform
  float std = 0.0f;      // for kNormal and kNormc
  size_t size() const { return static_cast<size_t>(rows) * cols; }
};

// A matrix the networks multiply by (registered by the layers for the bf16 products, nn/products.hpp): a
// kernel or a block of its rows, `rows` contiguous rows of `cols` floats from `offset`, and optionally its
// columns in another order (column j of the product's matrix is stored column col_map[j]).
struct ProductMatrix {
  size_t offset = 0;
  int rows = 0;
  int cols = 0;
  std::vector<int> col_map;  // empty: the stored order
};

// The list of slices; offsets grow as slices are added.
class ParamLayout {
 public:
  // A kernel [rows, cols] (decayed) or a vector [1, cols]; returns its offset.
  size_t add(ParamSlice slice);
  size_t add_kernel_xavier(const std::string& name, int rows, int cols, float fan_in, float fan_out);
  size_t add_kernel_normal(const std::string& name, int rows, int cols, float std);
  size_t add_kernel_normc(const std::string& name, int rows, int cols, float std);
  size_t add_vector(const std::string& name, int cols, Init init);

  // Registers a product matrix; returns its index in products().
  int add_product(ProductMatrix m);
  const std::vector<ProductMatrix>& products() const { return products_; }

  const std::vector<ParamSlice>& slices() const { return slices_; }
  size_t buffer_floats() const { return end_; }  // including alignment padding
  size_t num_params() const;                     // sum of slice sizes
  // nullptr if absent.
  const ParamSlice* find(const std::string& name) const;

 private:
  std::vector<ParamSlice> slices_;
  std::vector<ProductMatrix> products_;
  size_t end_ = 0;
};

// Owns the flat parameter and gradient buffers for a layout.
class ParamStore {
 public:
  ParamStore() = default;
  explicit ParamStore(ParamLayout layout);

  const ParamLayout& layout() const { return layout_; }
  float* values() { return values_.data(); }
  const float* values() const { return values_.data(); }
  float* grads() { return grads_.data(); }
  const float* grads() const { return grads_.data(); }
  size_t buffer_floats() const { return values_.size(); }

  // Values of one slice (a checked lookup by name).
  std::span<float> slice(const std::string& name);
  std::span<const float> slice(const std::string& name) const;

  // Initialises every slice from its Init, deterministically from the seed (slice i uses stream (seed, i)).
  void init(uint64_t seed);
  void zero_grads() { grads_.fill_zero(); }

 private:
  ParamLayout layout_;
  FloatBuffer values_;  // all parameters, buffer_floats()
  FloatBuffer grads_;   // all gradients, same layout
};

// Deterministic counter-based random numbers for initialisation and tests (SplitMix64 over (seed, stream,
// i)).
class InitRng {
 public:
  InitRng(uint64_t seed, uint64_t stream);
  uint64_t next_u64();
  double uniform();  // [0, 1)
  double normal();   // N(0, 1), Box-Muller

 private:
  uint64_t state_;
};

}  // namespace hns::nn
