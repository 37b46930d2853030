// What the compiled part of the Python package `hns` shares across its files: argument checks and array
// plumbing (read-only views kept alive by an owner, shapes and dtypes checked with errors naming the
// argument, paths and seeds from Python objects), and the binding functions PYBIND11_MODULE (hns_module.cpp)
// calls, one per file: the batch environment (batch_env.cpp), trained policies (policy.cpp), trajectory
// files, metrics and recordings (recordings.cpp).
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "physics/world.hpp"

namespace py = pybind11;

namespace hns::python {

namespace phys = hns::physics;
using Shape = std::vector<py::ssize_t>;

void bind_batch_env(py::module_& m);
void bind_policy(py::module_& m);
void bind_recordings(py::module_& m);

// A read-only array over `data` (C order) kept alive by `owner`; `as_bool` views 0/1 bytes as numpy bool.
template <class T>
py::array make_view(const T* data, const Shape& shape, const py::object& owner, bool as_bool = false) {
  py::dtype dtype = as_bool ? py::dtype("?") : py::dtype::of<T>();
  py::array a(dtype, shape, Shape{}, data, owner);
  a.attr("flags").attr("writeable") = false;
  return a;
}

// Copies of every array of a dict (copy=True results).
inline py::dict copy_dict(const py::dict& views) {
  py::dict out;
  for (auto item : views) out[item.first] = py::reinterpret_borrow<py::array>(item.second).attr("copy")();
  return out;
}

// Refuses a second concurrent call on one object (the GIL is released while it works).
class BusyGuard {
 public:
  BusyGuard(std::atomic<bool>& flag, const char* what) : flag_(flag) {
    if (flag_.exchange(true)) {
      throw std::runtime_error(std::string(what) +
                               ": called while another thread is inside a call on the same object");
    }
  }
  ~BusyGuard() { flag_ = false; }
  BusyGuard(const BusyGuard&) = delete;
  BusyGuard& operator=(const BusyGuard&) = delete;

 private:
  std::atomic<bool>& flag_;
};

// Sets a Python exception of `type` whose text is `message` as UTF-8, with any byte that is not (a damaged
// file's, echoed in the message) shown as U+FFFD rather than losing the whole message.
inline void set_error(PyObject* type, const std::string& message) {
  PyObject* text = PyUnicode_DecodeUTF8(message.data(), py::ssize_t(message.size()), "replace");
  if (text == nullptr) {  // out of memory: whatever Python raised stands
    return;
  }
  PyErr_SetObject(type, text);
  Py_DECREF(text);
}

[[noreturn]] inline void raise(PyObject* type, const std::string& message) {
  set_error(type, message);
  throw py::error_already_set();
}

inline std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}
inline std::string shape_text(const Shape& shape) {
  std::string s = "(";
  for (size_t i = 0; i < shape.size(); ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
  return s + (shape.size() == 1 ? ",)" : ")");
}

// `value` as an array (numpy converts lists); TypeError naming `what` otherwise.
inline py::array as_array(const py::handle& value, const std::string& what) {
  py::array a = py::array::ensure(value);
  if (!a)
    raise(PyExc_TypeError, what + ": expected a numpy array, got " + std::string(py::str(value.get_type())));
  return a;
}

inline void check_shape(const py::array& a, const Shape& want, const std::string& what) {
  bool ok = a.ndim() == py::ssize_t(want.size());
  for (size_t i = 0; ok && i < want.size(); ++i) ok = a.shape(i) == want[i];
  if (!ok) raise(PyExc_ValueError, what + ": shape " + shape_text(a) + ", expected " + shape_text(want));
}

// `a` as a C-contiguous array of T (converted where Flags include forcecast). A conversion numpy cannot make
// (no memory for the copy) is a MemoryError naming `what`, never a null array.
template <class T, int Flags = py::array::c_style>
py::array_t<T, Flags> contiguous(const py::array& a, const std::string& what) {
  auto c = py::array_t<T, Flags>::ensure(a);
  if (!c) raise(PyExc_MemoryError, what + ": no memory for a contiguous copy of shape " + shape_text(a));
  return c;
}

// A C-contiguous array of exactly T (no conversion: a wrong dtype is a TypeError naming `what`).
template <class T>
py::array_t<T, py::array::c_style> exact(const py::array& a, const std::string& what,
                                         const char* dtype_name) {
  if (!a.dtype().is(py::dtype::of<T>())) {
    raise(PyExc_TypeError, what + ": dtype " + std::string(py::str(a.dtype())) + ", expected " + dtype_name);
  }
  return contiguous<T>(a, what);
}

// A file path from a str or an os.PathLike (TypeError otherwise; ValueError for an embedded NUL byte).
inline std::string path_from(const py::object& value, const char* what) {
  const py::object p = py::module_::import("os").attr("fspath")(value);
  if (!py::isinstance<py::str>(p))
    raise(PyExc_TypeError, std::string(what) + ": expected a str or os.PathLike");
  std::string path = p.cast<std::string>();
  if (path.find('\0') != std::string::npos)
    raise(PyExc_ValueError, std::string(what) + ": the path holds a NUL byte");
  return path;
}

// A seed from any integer (Python or numpy; not bool) in [0, 2^64 - 1].
inline uint64_t seed_from(const py::object& value) {
  if (PyBool_Check(value.ptr()) || PyIndex_Check(value.ptr()) == 0) {
    raise(PyExc_TypeError, "seed: expected an integer, got " + std::string(py::str(value.get_type())));
  }
  const auto seed = py::reinterpret_steal<py::int_>(PyNumber_Index(value.ptr()));
  if (!seed) throw py::error_already_set();
  const py::int_ lo(0), hi(std::numeric_limits<uint64_t>::max());
  if (seed < lo || seed > hi) {
    raise(PyExc_ValueError,
          "seed = " + std::string(py::str(py::handle(seed))) + " is invalid: must be in [0, 2^64 - 1]");
  }
  return seed.cast<uint64_t>();
}

}  // namespace hns::python
