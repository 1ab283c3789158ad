// A whole trial through the offline pipeline of `fabrik solve` (solve_trial.hpp), to NumPy:
// the solution's vectors are moved into the arrays (positions scaled to mm in place); the
// coordinates are split by unit into angles (degrees) and translations (mm), their one copy.
#include <cmath>
#include <limits>

#include "bindings.hpp"
#include "offline/marker_match.hpp"
#include "offline/solve_trial.hpp"
#include "offline/subject_markers.hpp"
#include "recordings.hpp"

namespace fabrik::python {

namespace {

py::ssize_t ss(std::size_t n) {
  return static_cast<py::ssize_t>(n);
}

py::array_t<double> positions_mm(io::MarkerTrial& t) {
  const std::vector<py::ssize_t> shape{ss(t.frames()), ss(t.markers()), 3};  // before the move
  for (Eigen::Vector3d& p : t.positions_m) p *= kMmPerM;
  auto* heap = new std::vector<Eigen::Vector3d>(std::move(t.positions_m));
  py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<Eigen::Vector3d>*>(p); });
  return py::array_t<double>(shape, reinterpret_cast<const double*>(heap->data()), owner);
}

std::vector<double> scaled(std::vector<double>&& v, double factor) {
  for (double& x : v) x *= factor;
  return std::move(v);
}

// `dropped_samples`: samples past input.max_abs_coordinate_mm taken as missing (Python warns).
py::dict solution_dict(TrialSolution&& s, std::size_t dropped_samples) {
  const std::size_t frames = s.rms_m.size();
  py::dict d;
  std::vector<double> time_s(frames);
  std::vector<long long> numbers(frames);
  for (std::size_t f = 0; f < frames; ++f) {
    time_s[f] = s.joints.file_time_s(f);
    numbers[f] = s.joints.clock().number(f);
  }
  d["time_s"] = owned_array(std::move(time_s), {ss(frames)});
  d["frame_numbers"] = owned_array(std::move(numbers), {ss(frames)});
  d["rate_hz"] = s.joints.rate_hz;
  d["summary_json"] = solution_summary(s).dump();
  d["dropped_samples"] = dropped_samples;
  d["joint_names"] = s.joints.labels;
  d["marker_names"] = s.markers.labels;
  d["joints_mm"] = positions_mm(s.joints);
  d["markers_mm"] = positions_mm(s.markers);
  d["model_markers_mm"] = positions_mm(s.model_markers);
  d["residual_rms_mm"] = owned_array(scaled(std::move(s.rms_m), kMmPerM), {ss(frames)});
  d["residual_max_mm"] = owned_array(scaled(std::move(s.max_m), kMmPerM), {ss(frames)});
  d["solve_us"] = owned_array(std::move(s.solve_us), {ss(frames)});
  d["iterations"] = owned_array(std::move(s.iterations), {ss(frames)});
  d["measured"] = owned_array(std::move(s.measured), {ss(frames)});
  d["outlier_count"] = owned_array(std::move(s.outlier_count), {ss(frames)});
  d["status"] = s.status;
  std::vector<std::string> quality;
  for (FitQuality q : s.quality) quality.emplace_back(to_string(q));
  d["quality"] = quality;
  // Coordinates: [frame * names + c], split by unit.
  const std::size_t n = s.coordinate_names.size();
  std::vector<std::string> angle_names, translation_names;
  for (std::size_t c = 0; c < n; ++c)
    (s.coordinate_is_rotation[c] ? angle_names : translation_names)
        .push_back(s.coordinate_names[c]);
  std::vector<double> angles_deg, translations_mm;
  angles_deg.reserve(frames * angle_names.size());
  translations_mm.reserve(frames * translation_names.size());
  for (std::size_t f = 0; f < frames; ++f)
    for (std::size_t c = 0; c < n; ++c) {
      const double v = s.coordinates[f * n + c];
      if (s.coordinate_is_rotation[c])
        angles_deg.push_back(v * kDegPerRad);
      else
        translations_mm.push_back(v * kMmPerM);
    }
  const std::size_t angles = angle_names.size(), translations = translation_names.size();
  d["angle_names"] = angle_names;
  d["coordinate_names"] = s.coordinate_names;  // all of them, in the .mot's order
  d["translation_names"] = translation_names;
  d["angles_deg"] = owned_array(std::move(angles_deg), {ss(frames), ss(angles)});
  d["translations_mm"] = owned_array(std::move(translations_mm), {ss(frames), ss(translations)});
  d["missing_in_trial"] = s.missing_in_trial;
  d["ignored_in_trial"] = s.ignored_in_trial;
  std::vector<std::string> mostly;
  for (const MostlyMissing& mm : s.mostly_missing) mostly.push_back(mm.marker);
  d["mostly_missing"] = mostly;
  return d;
}

// The keyword that takes one subject of a `Subject:Marker` recording, for the hint.
constexpr const char* kSubjectKeyword = "subject=";

// `subject`'s markers, their labels without "subject:" (`fabrik solve --subject`); all of
// them when it is empty. The config that tracks them is subject_config's.
io::MarkerTrial of_subject(io::MarkerTrial&& trial, const std::string& subject) {
  return subject.empty() ? std::move(trial) : subject_trial(trial, subject, kSubjectKeyword);
}

// The keyword that lets a trial with fewer than half of the config's names be tracked.
constexpr const char* kAllowKeyword = "allow_missing_markers=True";

py::dict solve_file(const Config& config, const std::string& path, bool keep_zeros,
                    const std::string& subject, bool allow_missing_markers) {
  require_file(path, "recording");
  TrialSolution s;
  std::size_t implausible = 0;
  {
    py::gil_scoped_release unlocked;  // a trial takes seconds
    const DaemonConfig tracking = subject_config(*config.config, subject, kSubjectKeyword);
    io::MarkerTrial trial = of_subject(read_markers_file(path, keep_zeros), subject);
    // As fabrik solve and fabrikd: 1e300 in a file is not a measurement.
    implausible = drop_implausible_samples(trial, tracking.max_abs_coordinate_m);
    require_shared_markers(tracking, trial, path, kSubjectKeyword, allow_missing_markers,
                           kAllowKeyword);
    require_measured_marker(tracking, trial, path, implausible, "keep_zeros=True");
    s = solve_trial(tracking, trial);
  }
  return solution_dict(std::move(s), implausible);
}

py::dict solve_arrays(const Config& config, const std::vector<std::string>& names,
                      const py::array_t<double, py::array::c_style | py::array::forcecast>& mm,
                      double rate_hz, int first_frame, double first_time_s,
                      const std::string& subject, bool allow_missing_markers,
                      std::size_t zero_samples) {
  if (mm.ndim() != 3 || mm.shape(1) != ss(names.size()) || mm.shape(2) != 3)
    throw std::invalid_argument("positions_mm: expected shape (frames, " +
                                std::to_string(names.size()) + ", 3) for " +
                                std::to_string(names.size()) + " names");
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz))
    throw std::invalid_argument("rate_hz must be a positive number of frames per second");
  io::MarkerTrial trial;
  trial.labels = names;
  trial.rate_hz = rate_hz;
  trial.first_frame = first_frame;
  // Exact zeros Python turned into NaN (keep_zeros=False): said if nothing else is left.
  if (zero_samples > 0) trial.source.zero_samples = {zero_samples};
  // The data's own first time (a file read into MarkerData keeps its Time column's), as
  // solving the file would; NaN: frame first_frame at (first_frame - 1) / rate.
  if (std::isfinite(first_time_s)) trial.first_time_frames = first_time_s * rate_hz;
  trial.positions_m.resize(static_cast<std::size_t>(mm.shape(0)) * names.size());
  const double* p = mm.data();
  for (Eigen::Vector3d& x : trial.positions_m) {
    x = Eigen::Vector3d(p[0], p[1], p[2]) * kMPerMm;
    p += 3;
  }
  const DaemonConfig tracking = subject_config(*config.config, subject, kSubjectKeyword);
  trial = of_subject(std::move(trial), subject);
  const std::size_t implausible = drop_implausible_samples(trial, tracking.max_abs_coordinate_m);
  require_shared_markers(tracking, trial, "the markers", kSubjectKeyword, allow_missing_markers,
                         kAllowKeyword);
  require_measured_marker(tracking, trial, "the markers", implausible, "keep_zeros=True");
  TrialSolution s;
  {
    py::gil_scoped_release unlocked;
    s = solve_trial(tracking, trial);
  }
  return solution_dict(std::move(s), implausible);
}

}  // namespace

void bind_solve(py::module_& m) {
  m.def("_solve_file", &solve_file, py::arg("config"), py::arg("path"),
        py::arg("keep_zeros") = false, py::arg("subject") = "",
        py::arg("allow_missing_markers") = false);
  m.def("_solve_arrays", &solve_arrays, py::arg("config"), py::arg("names"),
        py::arg("positions_mm"), py::arg("rate_hz"), py::arg("first_frame") = 1,
        py::arg("first_time_s") = std::numeric_limits<double>::quiet_NaN(), py::arg("subject") = "",
        py::arg("allow_missing_markers") = false, py::arg("zero_samples") = 0);
}

}  // namespace fabrik::python
