#include "nn/params.hpp"

#include <cmath>
#include <numbers>

namespace hns::nn {

size_t ParamLayout::add(ParamSlice slice) {
  HNS_NN_CHECK(slice.rows > 0 && slice.cols > 0, "parameter slice " + slice.name + " is empty");
  HNS_NN_CHECK(find(slice.name) == nullptr, "duplicate parameter slice " + slice.name);
  slice.offset = end_;
  end_ += align_floats(slice.size());
  slices_.push_back(std::move(slice));
  return slices_.back().offset;
}

int ParamLayout::add_product(ProductMatrix m) {
  HNS_NN_CHECK(m.rows > 0 && m.cols > 0 && m.offset + size_t(m.rows) * m.cols <= end_,
               "product matrix outside the registered parameters");
  HNS_NN_CHECK(m.col_map.empty() || m.col_map.size() == size_t(m.cols),
               "product column map of another width");
  products_.push_back(std::move(m));
  return static_cast<int>(products_.size()) - 1;
}

size_t ParamLayout::add_kernel_xavier(const std::string& name, int rows, int cols, float fan_in,
                                      float fan_out) {
  ParamSlice s;
  s.name = name;
  s.rows = rows;
  s.cols = cols;
  s.decay = true;
  s.init = Init::kXavierUniform;
  s.fan_in = fan_in;
  s.fan_out = fan_out;
  return add(std::move(s));
}

size_t ParamLayout::add_kernel_normal(const std::string& name, int rows, int cols, float std) {
  ParamSlice s;
  s.name = name;
  s.rows = rows;
  s.cols = cols;
  s.decay = true;
  s.init = Init::kNormal;
  s.std = std;
  return add(std::move(s));
}

size_t ParamLayout::add_kernel_normc(const std::string& name, int rows, int cols, float std) {
  ParamSlice s;
  s.name = name;
  s.rows = rows;
  s.cols = cols;
  s.decay = true;
  s.init = Init::kNormc;
  s.std = std;
  return add(std::move(s));
}

size_t ParamLayout::add_vector(const std::string& name, int cols, Init init) {
  ParamSlice s;
  s.name = name;
  s.rows = 1;
  s.cols = cols;
  s.init = init;
  return add(std::move(s));
}

size_t ParamLayout::num_params() const {
  size_t n = 0;
  for (const auto& s : slices_) n += s.size();
  return n;
}

const ParamSlice* ParamLayout::find(const std::string& name) const {
  for (const auto& s : slices_)
    if (s.name == name) return &s;
  return nullptr;
}

ParamStore::ParamStore(ParamLayout layout)
    : layout_(std::move(layout)), values_(layout_.buffer_floats()), grads_(layout_.buffer_floats()) {}

std::span<float> ParamStore::slice(const std::string& name) {
  const ParamSlice* s = layout_.find(name);
  HNS_NN_CHECK(s != nullptr, "no parameter slice named " + name);
  return {values_.data() + s->offset, s->size()};
}

std::span<const float> ParamStore::slice(const std::string& name) const {
  const ParamSlice* s = layout_.find(name);
  HNS_NN_CHECK(s != nullptr, "no parameter slice named " + name);
  return {values_.data() + s->offset, s->size()};
}

void ParamStore::init(uint64_t seed) {
  values_.fill_zero();
  const auto& slices = layout_.slices();
  for (size_t i = 0; i < slices.size(); ++i) {
    const ParamSlice& s = slices[i];
    float* v = values_.data() + s.offset;
    InitRng rng(seed, i);
    switch (s.init) {
      case Init::kZeros:
        break;
      case Init::kOnes:
        for (size_t k = 0; k < s.size(); ++k) v[k] = 1.0f;
        break;
      case Init::kXavierUniform: {
        const double a = std::sqrt(6.0 / (static_cast<double>(s.fan_in) + s.fan_out));
        for (size_t k = 0; k < s.size(); ++k) v[k] = static_cast<float>((2.0 * rng.uniform() - 1.0) * a);
        break;
      }
      case Init::kNormal:
        for (size_t k = 0; k < s.size(); ++k) v[k] = static_cast<float>(rng.normal() * s.std);
        break;
      case Init::kNormc: {
        // Draw row-major, then rescale each output column to norm `std`.
        std::vector<double> w(s.size());
        for (auto& x : w) x = rng.normal();
        for (int c = 0; c < s.cols; ++c) {
          double ss = 0.0;
          for (int r = 0; r < s.rows; ++r)
            ss += w[static_cast<size_t>(r) * s.cols + c] * w[static_cast<size_t>(r) * s.cols + c];
          const double scale = s.std / std::sqrt(ss);
          for (int r = 0; r < s.rows; ++r)
            v[static_cast<size_t>(r) * s.cols + c] =
                static_cast<float>(w[static_cast<size_t>(r) * s.cols + c] * scale);
        }
        break;
      }
    }
  }
}

namespace {
// SplitMix64's output function.
uint64_t mix64(uint64_t x) {
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
}  // namespace

InitRng::InitRng(uint64_t seed, uint64_t stream)
    : state_(mix64(mix64(seed + 0x9E3779B97F4A7C15ull) ^ (stream * 0xD1B54A32D192ED03ull))) {}

uint64_t InitRng::next_u64() {
  state_ += 0x9E3779B97F4A7C15ull;
  return mix64(state_);
}

double InitRng::uniform() {
  return static_cast<double>(next_u64() >> 11) * 0x1.0p-53;
}

double InitRng::normal() {
  // Box-Muller with u1 in (0, 1].
  const double u1 = 1.0 - uniform();
  const double u2 = uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

}  // namespace hns::nn
