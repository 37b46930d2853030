// The checkpoint payload's writer and reader (ppo/checkpoint.cpp has the file format), for the parts of the
// trainer that write their own section of a checkpoint (ppo/intrinsic_reward.hpp). Values are stored as
// their bytes (little-endian on the machines hns runs on); an array is its length (u64) then its elements.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace hns::ppo {

class CheckpointWriter {
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

class CheckpointReader {
 public:
  CheckpointReader(const char* p, size_t n, const std::string& path) : p_(p), n_(n), path_(path) {}
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
  // The length of the array that starts here (without reading it).
  uint64_t peek_length() {
    need(sizeof(uint64_t));
    uint64_t n;
    std::memcpy(&n, p_ + i_, sizeof n);
    if (n > (n_ - i_) / sizeof(uint32_t))
      throw std::runtime_error("checkpoint " + path_ + " is truncated inside its payload");
    return n;
  }

 private:
  void need(uint64_t bytes) const {
    if (bytes > n_ - i_) throw std::runtime_error("checkpoint " + path_ + " is truncated inside its payload");
  }
  const char* p_;
  size_t n_;
  size_t i_ = 0;
  std::string path_;
};

// Refuses (refuse(reason)) the first value of p[0, n) that is not finite, or negative where non_negative,
// naming the array `what`, the value and its index.
template <class T>
void refuse_bad_values(const std::function<void(const std::string&)>& refuse, const std::string& what,
                       const T* p, size_t n, bool non_negative) {
  for (size_t i = 0; i < n; ++i) {
    if (std::isfinite(double(p[i])) && !(non_negative && p[i] < 0)) continue;
    refuse(what + " has " + std::to_string(double(p[i])) + " at index " + std::to_string(i) +
           (non_negative ? " (values must be finite and at least 0)" : " (values must be finite)"));
    return;
  }
}

}  // namespace hns::ppo
