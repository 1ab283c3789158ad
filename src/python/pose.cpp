// Pose: the copy out of the Tracker's result and the Python view of it (pose.hpp).
#include "pose.hpp"

#include <algorithm>

namespace fabrik::python {

PoseLayout::PoseLayout(const Tracker& tracker) {
  const Model& model = tracker.model();
  marker_names = names_of(tracker.setup().markers, &MarkerTarget::marker);
  joint_names = names_of(model.joints, &Joint::name);
  segment_names = names_of(model.segments, &Segment::name);
  for (const Coordinate& c : model.coordinates) {
    coordinate_names.push_back(c.name);
    coordinate_is_rotation.push_back(c.kind == CoordinateKind::rotation);
  }
  markers = marker_names.size();
  joints = joint_names.size();
  segments = segment_names.size();
  coordinates = coordinate_names.size();
  joints_at = 0;
  markers_at = joints_at + 3 * joints;
  q_at = markers_at + 3 * markers;
  origin_at = q_at + 4 * segments;
  coordinates_at = origin_at + 3 * segments;
  residual_at = coordinates_at + coordinates;
  numbers = residual_at + markers;
  occluded_at = 0;
  held_at = markers;
  outlier_at = 2 * markers;
  flags = 3 * markers;
}

namespace {
void copy_mm(std::span<const Eigen::Vector3d> from_m, double* to_mm) {
  for (const Eigen::Vector3d& p : from_m) {
    to_mm[0] = p.x() * kMmPerM;
    to_mm[1] = p.y() * kMmPerM;
    to_mm[2] = p.z() * kMmPerM;
    to_mm += 3;
  }
}
}  // namespace

Pose::Pose(std::shared_ptr<const PoseLayout> l, double t_s, double t_us, const TrackResult& r)
    : layout(std::move(l)),
      time_s(t_s),
      track_us(t_us),
      solve_us(r.solve_us),
      status(to_string(r.solve.status)),
      quality(to_string(r.quality)),
      iterations(r.solve.iterations),
      residual_count(r.residual_count),
      worst_marker(r.worst_marker),
      occluded_count(r.occluded_count),
      low_confidence_count(r.low_confidence_count),
      residual_rms_mm(r.residual_rms_m * kMmPerM),
      residual_max_mm(r.residual_max_m * kMmPerM),
      cold_start(r.cold_start),
      numbers(layout->numbers),
      flags(layout->flags) {
  const PoseLayout& L = *layout;
  double* n = numbers.data();
  copy_mm(r.joints_world_m, n + L.joints_at);
  copy_mm(r.markers_world_m, n + L.markers_at);
  for (std::size_t s = 0; s < r.segment_q_world.size(); ++s) {
    const Eigen::Quaterniond& q = r.segment_q_world[s];
    double* out = n + L.q_at + 4 * s;
    out[0] = q.w();
    out[1] = q.x();
    out[2] = q.y();
    out[3] = q.z();
  }
  copy_mm(r.segment_origin_world_m, n + L.origin_at);
  for (std::size_t c = 0; c < r.coordinates.size(); ++c)
    n[L.coordinates_at + c] =
        r.coordinates[c] * (L.coordinate_is_rotation[c] ? kDegPerRad : kMmPerM);
  for (std::size_t i = 0; i < r.marker_residual_m.size(); ++i)
    n[L.residual_at + i] = r.marker_residual_m[i] * kMmPerM;
  std::copy(r.occluded.begin(), r.occluded.end(), flags.begin() + L.occluded_at);
  std::copy(r.held.begin(), r.held.end(), flags.begin() + L.held_at);
  std::copy(r.outliers.begin(), r.outliers.end(), flags.begin() + L.outlier_at);
}

namespace {

// Pose.<name>: a (rows, columns) view of the pose's numbers from layout.*at (columns 0: 1-D),
// keeping the pose alive.
void def_numbers(py::class_<Pose>& cls, const char* name, std::size_t PoseLayout::*at,
                 std::size_t PoseLayout::*rows, py::ssize_t columns, const char* doc) {
  cls.def_property_readonly(
      name,
      [at, rows, columns](const py::object& self) {
        Pose& p = self.cast<Pose&>();
        const PoseLayout& L = *p.layout;
        std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(L.*rows)};
        if (columns > 0) shape.push_back(columns);
        return py::array_t<double>(std::move(shape), p.numbers.data() + L.*at, self);
      },
      doc);
}

// Pose.<name>: a (markers,) bool view of the pose's flags from layout.*at.
void def_flags(py::class_<Pose>& cls, const char* name, std::size_t PoseLayout::*at,
               const char* doc) {
  cls.def_property_readonly(
      name,
      [at](const py::object& self) {
        Pose& p = self.cast<Pose&>();
        return py::array(py::dtype("bool"), {static_cast<py::ssize_t>(p.layout->markers)},
                         p.flags.data() + (*p.layout).*at, self);
      },
      doc);
}

py::dict coordinate_dict(const Pose& p, bool rotations) {
  py::dict d;
  const PoseLayout& L = *p.layout;
  for (std::size_t c = 0; c < L.coordinates; ++c)
    if (static_cast<bool>(L.coordinate_is_rotation[c]) == rotations)
      d[py::str(L.coordinate_names[c])] = p.numbers[L.coordinates_at + c];
  return d;
}

}  // namespace

void bind_pose(py::module_& m) {
  py::class_<Pose> cls(m, "Pose",
                       "One tracked frame. Lengths in mm, in the lab (world) frame of the input; "
                       "angles in degrees. Arrays view the pose's own copy of the frame: they stay "
                       "valid after the next track() and may be kept.");
  cls.def_readonly("time_s", &Pose::time_s)
      .def_property_readonly(
          "status", [](const Pose& p) { return std::string(p.status); },
          "The solver's stop reason: converged, stalled, max_iterations, "
          "no_targets or size_mismatch (a value, never an exception)")
      .def_readonly("iterations", &Pose::iterations)
      .def_readonly("solve_us", &Pose::solve_us, "Wall time of the solve itself (us)")
      .def_readonly("track_us", &Pose::track_us,
                    "Wall time of the C++ Tracker::track call (us): the rest of a track() "
                    "call is the Python edge (python3 -m fabrik.bench)")
      .def_property_readonly(
          "angles_deg", [](const Pose& p) { return coordinate_dict(p, true); },
          "The model's rotational coordinates (name -> degrees), as on the "
          "wire and in `fabrik solve --angles`; continuous over frames")
      .def_property_readonly(
          "translations_mm", [](const Pose& p) { return coordinate_dict(p, false); },
          "The model's translational coordinates (name -> mm)")
      .def_readonly("occluded_count", &Pose::occluded_count)
      .def_readonly("low_confidence_count", &Pose::low_confidence_count,
                    "Of occluded_count: markers measured but occluded by a confidence below "
                    "the config's confidence.threshold (track() with a 4th value per marker)")
      .def_readonly("residual_rms_mm", &Pose::residual_rms_mm,
                    "RMS over the markers measured and solved with, mm")
      .def_readonly("residual_max_mm", &Pose::residual_max_mm)
      .def_readonly("residual_count", &Pose::residual_count)
      .def_property_readonly(
          "worst_marker",
          [](const Pose& p) -> py::object {
            if (p.worst_marker < 0) return py::none();
            return py::str(p.layout->marker_names[static_cast<std::size_t>(p.worst_marker)]);
          },
          "Name of the marker farthest from its model position, None when none was measured")
      .def_property_readonly(
          "quality", [](const Pose& p) { return std::string(p.quality); },
          "good, poor (against the config's quality thresholds) or none")
      .def_readonly("cold_start", &Pose::cold_start)
      .def("__repr__", [](const Pose& p) {
        return "<fabrik.Pose t=" + std::to_string(p.time_s) + " s " + std::string(p.status) +
               ", residual " + std::to_string(p.residual_rms_mm) + " mm RMS, " +
               std::to_string(p.occluded_count) + " occluded>";
      });
  using L = PoseLayout;
  def_numbers(cls, "joints_mm", &L::joints_at, &L::joints, 3,
              "(joints, 3) joint centres, mm, in Tracker.joint_names order");
  def_numbers(cls, "markers_mm", &L::markers_at, &L::markers, 3,
              "(markers, 3) the model's markers (where the model puts them, occluded ones "
              "included), mm, in Tracker.marker_names order");
  def_numbers(cls, "segment_q_world", &L::q_at, &L::segments, 4,
              "(segments, 4) each segment's anatomical frame's rotation in the world, unit "
              "quaternions (w, x, y, z), in Tracker.segment_names order");
  def_numbers(cls, "segment_origin_mm", &L::origin_at, &L::segments, 3,
              "(segments, 3) each segment's base (origin) in the world, mm");
  def_numbers(cls, "marker_residual_mm", &L::residual_at, &L::markers, 0,
              "(markers,) distance from each measurement to its model marker, mm; NaN when not "
              "measured");
  def_flags(cls, "occluded", &L::occluded_at,
            "(markers,) bool: no valid measurement (absent, NaN)");
  def_flags(cls, "held", &L::held_at,
            "(markers,) bool: occluded, but its last position still pulled (occlusion.hold_s)");
  def_flags(cls, "outliers", &L::outlier_at,
            "(markers,) bool: measured, but left out of the solve as an outlier");
}

}  // namespace fabrik::python
