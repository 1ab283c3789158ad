// The C++ side of `python3 -m fabrik.bench` (docs/python.md): the same frames through a C++
// loop over Tracker::track, the baseline a Python track() call is compared with; and smooth
// synthetic frames of a config's model (synthetic_motion.hpp) to track.
#include <chrono>
#include <cmath>

#include "bindings.hpp"
#include "solver/posture.hpp"
#include "synth/synthetic_motion.hpp"

namespace fabrik::python {

namespace {

using Frames = py::array_t<double, py::array::c_style | py::array::forcecast>;

// (frames, markers, 3) mm: the config's tracked markers on a smooth motion, with noise.
py::array_t<double> synthetic_frames(const Config& config, std::size_t frames, double rate_hz,
                                     double noise_mm, unsigned seed) {
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz))
    throw std::invalid_argument("rate_hz must be a positive number of frames per second");
  if (!(noise_mm >= 0.0) || !std::isfinite(noise_mm))
    throw std::invalid_argument("noise_mm must be a finite number of mm, 0 or more");
  const TrackerSetup& setup = config.config->tracker;
  const Model& model = *setup.model;
  MotionSettings settings;
  settings.seed = seed;
  SyntheticMotion motion(model, settings);
  Posture posture = Posture::rest(model);
  std::vector<int> points;
  for (const MarkerTarget& t : setup.markers) points.push_back(t.point);
  std::vector<Eigen::Vector3d> sample_m(points.size());
  std::vector<double> mm;
  mm.reserve(frames * points.size() * 3);
  for (std::size_t f = 0; f < frames; ++f) {
    motion.posture_at(static_cast<double>(f) / rate_hz, posture);
    motion.sample(posture, points, noise_mm * kMPerMm, sample_m);
    for (const Eigen::Vector3d& p : sample_m)
      for (int k = 0; k < 3; ++k) mm.push_back(p[k] * kMmPerM);
  }
  return owned_array(std::move(mm), {static_cast<py::ssize_t>(frames),
                                     static_cast<py::ssize_t>(points.size()), 3});
}

// Wall time of each Tracker::track call (us), the frames tracked in order from a cold start by
// a Tracker of this config, the input already in metres as fabrikd has it.
std::vector<double> bench_track_cpp(const Config& config, const Frames& frames_mm, double rate_hz) {
  const std::size_t markers = config.config->tracker.markers.size();
  if (frames_mm.ndim() != 3 || frames_mm.shape(1) != static_cast<py::ssize_t>(markers) ||
      frames_mm.shape(2) != 3)
    throw std::invalid_argument("frames_mm: expected shape (frames, " + std::to_string(markers) +
                                ", 3)");
  const auto frames = static_cast<std::size_t>(frames_mm.shape(0));
  std::vector<Eigen::Vector3d> all_m(frames * markers);
  const double* p = frames_mm.data();
  for (Eigen::Vector3d& x : all_m) {
    x = Eigen::Vector3d(p[0], p[1], p[2]) * kMPerMm;
    p += 3;
  }
  const std::vector<std::uint8_t> visible(markers, 1);
  Tracker tracker(config.config->tracker);
  std::vector<double> us(frames);
  py::gil_scoped_release unlocked;
  for (std::size_t f = 0; f < frames; ++f) {
    const auto start = std::chrono::steady_clock::now();
    tracker.track(static_cast<double>(f) / rate_hz,
                  std::span<const Eigen::Vector3d>(all_m.data() + f * markers, markers), visible);
    const std::chrono::duration<double, std::micro> took = std::chrono::steady_clock::now() - start;
    us[f] = took.count();
  }
  return us;
}

}  // namespace

void bind_bench(py::module_& m) {
  m.def("synthetic_frames", &synthetic_frames, py::arg("config"), py::arg("frames"),
        py::arg("rate_hz") = 100.0, py::arg("noise_mm") = 0.5, py::arg("seed") = 1u,
        "(frames, markers, 3) mm: the config's tracked markers (Config.marker_names order) on "
        "a smooth synthetic motion of its model (every joint swinging, the root travelling), "
        "with Gaussian noise per axis; frame f is at f / rate_hz seconds");
  m.def("_bench_track_cpp", &bench_track_cpp, py::arg("config"), py::arg("frames_mm"),
        py::arg("rate_hz") = 100.0);
}

}  // namespace fabrik::python
