// The parts of the extension `fabrik._fabrik`, one registration function per topic (one file
// each), and the helpers they share. Lengths cross the Python edge in millimetres (as on the
// wire and in TRC files) and are converted to the tracker's metres once, here.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "config/daemon_config.hpp"

namespace fabrik::python {

namespace py = pybind11;

inline constexpr double kMmPerM = 1000.0;
inline constexpr double kMPerMm = 1e-3;
inline constexpr double kDegPerRad = 180.0 / 3.141592653589793;

// A loaded daemon config, shared by the Trackers made from it (the model is immutable).
struct Config {
  std::shared_ptr<const DaemonConfig> config;
  std::string json;    // the config's text as loaded (pickling sends it)
  std::string report;  // calibrate: the summary `fabrik calibrate` prints, else ""
  // The file as an absolute path, taken when it was loaded (pickling sends it: the other side
  // may run in another folder, and this one may have changed folder since).
  std::string absolute_file;
};

// A vector moved into a NumPy array that owns it (a capsule frees it): no copy.
template <class T>
py::array_t<T> owned_array(std::vector<T>&& values, std::vector<py::ssize_t> shape) {
  auto* heap = new std::vector<T>(std::move(values));
  py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(std::move(shape), heap->data(), owner);
}

// FileNotFoundError naming the path when it does not exist (the C++ readers would say
// "cannot read" as a ValueError, which hides the usual mistake).
void require_file(const std::string& path, const std::string& what);

// The names of a list of markers, joints, segments...: names_of(model.joints, &Joint::name).
template <class T>
std::vector<std::string> names_of(const std::vector<T>& items, std::string T::*name) {
  std::vector<std::string> names;
  names.reserve(items.size());
  for (const T& item : items) names.push_back(item.*name);
  return names;
}

void bind_errors(py::module_& m);
void bind_config(py::module_& m);
void bind_tracker(py::module_& m);
void bind_recordings(py::module_& m);
void bind_solve(py::module_& m);
void bind_bench(py::module_& m);

}  // namespace fabrik::python
