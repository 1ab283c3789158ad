// Recordings into NumPy: marker trials (TRC, C3D) as (frames, markers, 3) millimetres, and
// OpenSim tables (MOT, STO) with their values as the file has them. The readers' vectors are
// moved into the arrays (no copy); marker positions are scaled to mm in place.
#include "recordings.hpp"
#include "bindings.hpp"
#include "io/marker_trial.hpp"
#include "io/opensim_table.hpp"

namespace fabrik::python {

py::dict marker_trial_dict(io::MarkerTrial&& trial) {
  const auto frames = static_cast<py::ssize_t>(trial.frames());
  const auto markers = static_cast<py::ssize_t>(trial.markers());
  std::vector<double> time_s(trial.frames());
  std::vector<long long> frame_numbers(trial.frames());
  for (std::size_t f = 0; f < trial.frames(); ++f) {
    time_s[f] = trial.file_time_s(f);
    frame_numbers[f] = trial.clock().number(f);
  }
  for (Eigen::Vector3d& p : trial.positions_m) p *= kMmPerM;
  // Eigen::Vector3d is three packed doubles, so the vector's memory is a (frames, markers, 3)
  // array of doubles. Moved whole into the array's owner, then viewed.
  static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double));
  auto* heap = new std::vector<Eigen::Vector3d>(std::move(trial.positions_m));
  py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<Eigen::Vector3d>*>(p); });
  py::array_t<double> positions({frames, markers, py::ssize_t{3}},
                                reinterpret_cast<const double*>(heap->data()), owner);
  py::dict d;
  d["names"] = trial.labels;
  d["positions_mm"] = positions;
  d["time_s"] = owned_array(std::move(time_s), {frames});
  d["frame_numbers"] = owned_array(std::move(frame_numbers), {frames});
  d["rate_hz"] = trial.rate_hz;
  d["first_frame"] = trial.first_frame;
  d["file_units"] = trial.source.units;
  d["format"] = trial.source.format;
  d["warnings"] = trial.warnings;
  return d;
}

io::MarkerTrial read_markers_file(const std::string& path, bool keep_zeros) {
  io::ReadOptions options;
  options.zeros_are_missing = !keep_zeros;
  io::MarkerTrial trial = io::read_trial(path, options);
  io::require_marker_data(trial, path);
  return trial;
}

namespace {

py::dict read_markers(const std::string& path, bool keep_zeros) {
  require_file(path, "recording");
  io::MarkerTrial trial;
  {
    py::gil_scoped_release unlocked;
    trial = read_markers_file(path, keep_zeros);
  }
  return marker_trial_dict(std::move(trial));
}

py::dict read_table(const std::string& path) {
  require_file(path, "table");
  io::OpenSimTable t;
  {
    py::gil_scoped_release unlocked;
    // Described as fabrik info describes it: a bad cell NaN (its row kept), a time going back said.
    t = io::read_opensim_table(path, {.bad_cells_missing = true, .refuse_time_back = false});
  }
  if (t.columns.empty()) throw io::FormatError(path, "no column labels (time first)");
  const auto rows = static_cast<py::ssize_t>(t.rows);
  const auto columns = static_cast<py::ssize_t>(t.columns.size() - 1);
  std::vector<py::ssize_t> shape{rows, columns};
  if (t.cell_width > 1) shape.push_back(static_cast<py::ssize_t>(t.cell_width));
  py::dict d;
  d["names"] = std::vector<std::string>(t.columns.begin() + 1, t.columns.end());
  d["time_s"] = owned_array(std::move(t.time_s), {rows});
  d["data"] = owned_array(std::move(t.values), shape);
  d["rate_hz"] = t.rate_hz;
  d["in_degrees"] = t.in_degrees();
  d["cell_kind"] = t.cell_kind;
  py::dict header;
  for (const auto& [key, value] : t.header) header[py::str(key)] = value;
  d["header"] = header;
  d["name"] = t.name;
  d["warnings"] = t.warnings;
  return d;
}

}  // namespace

void bind_recordings(py::module_& m) {
  m.def("_read_markers", &read_markers, py::arg("path"), py::arg("keep_zeros") = false);
  m.def("_read_table", &read_table, py::arg("path"));
}

}  // namespace fabrik::python
