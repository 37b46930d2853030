// Tensors as views over caller-owned memory, the aligned buffers that own that memory, and the bump arena
// that carves a workspace into named buffers once per batch shape. Nothing in forward/backward allocates:
// layers read and write through these views only.
#pragma once

#include <Eigen/Core>

#include <cassert>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>
#include <span>
#include <stdexcept>
#include <string>

#include "common/aligned_buffer.hpp"

namespace hns::nn {

inline constexpr size_t kAlignBytes = AlignedBuffer<float>::kAlignment;
inline constexpr size_t kAlignFloats = kAlignBytes / sizeof(float);

// Rounds n floats up to a whole number of 64-byte lines.
inline constexpr size_t align_floats(size_t n) {
  return (n + kAlignFloats - 1) / kAlignFloats * kAlignFloats;
}

// Always-on check for broken set-up invariants (not for hot paths).
#define HNS_NN_CHECK(cond, msg)                                                                      \
  do {                                                                                               \
    if (!(cond))                                                                                     \
      throw std::logic_error(std::string(__FILE__) + ":" + std::to_string(__LINE__) + ": " + (msg)); \
  } while (0)

// A fixed-size, 64-byte aligned, zero-initialised float array (move-only): the one aligned buffer type.
using FloatBuffer = AlignedBuffer<float>;

// Row-major matrix view: rows x cols, consecutive rows `stride` floats apart (stride >= cols).
// A [rows, entities, features] tensor is the view [rows * entities, features]; one entity slot of it is the
// view [rows, features] with stride entities * features.
template <class T>
struct MatView {
  using RowMat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  using EigenMap = Eigen::Map<std::conditional_t<std::is_const_v<T>, const RowMat, RowMat>, Eigen::Unaligned,
                              Eigen::OuterStride<>>;

  T* data = nullptr;
  int rows = 0;
  int cols = 0;
  int stride = 0;

  MatView() = default;
  MatView(T* d, int r, int c) : data(d), rows(r), cols(c), stride(c) {}
  MatView(T* d, int r, int c, int s) : data(d), rows(r), cols(c), stride(s) { assert(s >= c); }
  // A mutable view converts to a read-only one.
  template <class U, class = std::enable_if_t<std::is_const_v<T> && std::is_same_v<const U, T>>>
  MatView(const MatView<U>& o) : data(o.data), rows(o.rows), cols(o.cols), stride(o.stride) {}  // NOLINT

  T* row(int r) const { return data + static_cast<ptrdiff_t>(r) * stride; }
  T& at(int r, int c) const { return data[static_cast<ptrdiff_t>(r) * stride + c]; }
  bool empty() const { return data == nullptr; }
  // Rows [first, first + count).
  MatView block_rows(int first, int count) const { return {row(first), count, cols, stride}; }
  // Every `step`-th row starting at `first` (e.g. one time step of a [sequences * steps, f] tensor).
  MatView every(int first, int step, int count) const { return {row(first), count, cols, stride * step}; }
  EigenMap map() const { return EigenMap(data, rows, cols, Eigen::OuterStride<>(stride)); }
};
using Mat = MatView<float>;
using CMat = MatView<const float>;

// Bump allocator over one aligned buffer. Used in two passes: a counting pass (no storage; take() returns
// nullptr and only sums sizes) to size the workspace, then the real pass over the allocated buffer.
class Arena {
 public:
  Arena() = default;  // counting mode
  Arena(float* base, size_t capacity) : base_(base), capacity_(capacity) {}

  // n floats, 64-byte aligned; nullptr in counting mode.
  float* take(size_t n) {
    float* p = base_ == nullptr ? nullptr : base_ + used_;
    used_ += align_floats(n);
    HNS_NN_CHECK(base_ == nullptr || used_ <= capacity_, "workspace arena overflow");
    return p;
  }
  // n int32 (index lists next to the activations; the storage is raw memory, only ever read as int32).
  int32_t* take_ints(size_t n) { return reinterpret_cast<int32_t*>(take(n)); }
  size_t used() const { return used_; }

 private:
  float* base_ = nullptr;
  size_t capacity_ = 0;
  size_t used_ = 0;
};

// A workspace sized once for one batch shape: `Bufs` is a struct of float pointers with a
// `void bind(Arena&)` that takes each of them from the arena in a fixed order.
template <class Bufs>
class Workspace {
 public:
  Workspace() = default;
  template <class... Args>
  explicit Workspace(Args&&... shape) : bufs_(std::forward<Args>(shape)...) {
    Arena counter;
    bufs_.bind(counter);
    storage_.resize(counter.used());
    Arena arena(storage_.data(), storage_.size());
    bufs_.bind(arena);
  }
  Bufs& bufs() { return bufs_; }
  const Bufs& bufs() const { return bufs_; }
  size_t floats() const { return storage_.size(); }

 private:
  Bufs bufs_;
  FloatBuffer storage_;
};

}  // namespace hns::nn
