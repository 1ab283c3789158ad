// Tracker: the daemon's per-frame pipeline driven from Python. Markers come in as a dict
// (name -> x, y, z[, confidence]) or a (markers, 3) or (markers, 4) array in
// Tracker.marker_names order, in millimetres; they are converted to metres once, into buffers
// sized here, and tracked as fabrikd tracks a frame (a 4th value is the wire's confidence).
// The GIL stays held: a frame is tens of microseconds, less than a thread switch costs.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <span>

#include "pose.hpp"
#include "tracking/confidence.hpp"

namespace fabrik::python {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A marker's confidence as the daemon reads a wire frame's 4th value; one that is not finite
// occludes the marker (its position NaN).
float confidence_of(double confidence, Eigen::Vector3d& measured_m) {
  const std::optional<float> clamped = clamped_confidence(confidence);
  if (!clamped) measured_m.setConstant(kNaN);
  return clamped.value_or(0.0f);
}

class PyTracker {
 public:
  explicit PyTracker(const Config& config)
      : config_(config),
        tracker_(std::make_unique<Tracker>(config_.config->tracker)),
        layout_(std::make_shared<const PoseLayout>(*tracker_)),
        measured_m_(layout_->markers),
        visible_(layout_->markers, 1),
        confidence_(layout_->markers, 1.0f) {
    for (std::size_t i = 0; i < layout_->markers; ++i)
      index_[py::str(layout_->marker_names[i])] = py::int_(i);
  }

  Pose track(const py::handle& markers, double time_s, bool ignore_unknown) {
    // A NaN time would stay in the tracker's clock (one NaN frame turned the hold policy off
    // for the frames after it): refused here, where Python's floats come in.
    if (!std::isfinite(time_s))
      throw std::invalid_argument("time_s must be a finite number of seconds");
    with_confidence_ = false;
    if (PyDict_Check(markers.ptr()))
      read_dict(markers, ignore_unknown);
    else
      read_array(markers);
    // Timed so that the bench (and a caller) can tell the edge's cost from the tracker's.
    const auto start = std::chrono::steady_clock::now();
    // Confidences only when the frame gave one (as the daemon): the others' stay 1.
    const TrackResult& r = with_confidence_ ? tracker_->track(time_s, measured_m_, visible_,
                                                              std::span<const float>(confidence_))
                                            : tracker_->track(time_s, measured_m_, visible_);
    const std::chrono::duration<double, std::micro> took = std::chrono::steady_clock::now() - start;
    return Pose(layout_, time_s, took.count(), r);
  }

  void reset() { tracker_->reset(); }
  const PoseLayout& layout() const { return *layout_; }
  const Config& config() const { return config_; }

 private:
  // Absent names are occluded; NaN coordinates too (the tracker's rule). Callers usually pass
  // dicts built the same way every frame, so the keys come as the same str objects in the same
  // order: the key at position k is checked against the one seen there last time by identity
  // (held references, so an identical address is the same immutable str), and only a new key
  // is hashed and looked up: about 0.9 us less per 45-marker frame (docs/python.md).
  void read_dict(const py::handle& markers, bool ignore_unknown) {
    for (Eigen::Vector3d& p : measured_m_) p.setConstant(kNaN);
    std::fill(confidence_.begin(), confidence_.end(), 1.0f);
    PyObject* key = nullptr;
    PyObject* value = nullptr;
    Py_ssize_t pos = 0;
    std::size_t k = 0;
    while (PyDict_Next(markers.ptr(), &pos, &key, &value)) {
      int i = -1;
      if (k < seen_keys_.size() && seen_keys_[k].ptr() == key) {
        i = seen_index_[k];
      } else {
        PyObject* found = PyDict_GetItemWithError(index_.ptr(), key);
        if (!found && PyErr_Occurred()) throw py::error_already_set();
        i = found ? static_cast<int>(PyLong_AsLong(found)) : -1;
        remember(k, key, i);
      }
      if (i < 0 && !ignore_unknown) throw py::key_error(unknown_name(key));
      if (i >= 0) {
        const auto m = static_cast<std::size_t>(i);
        double confidence = 1.0;
        if (read_xyz(value, key, measured_m_[m], confidence)) {
          confidence_[m] = confidence_of(confidence, measured_m_[m]);
          with_confidence_ = true;
        }
      }
      ++k;
    }
  }

  void remember(std::size_t k, PyObject* key, int index) {
    if (k >= kRememberedKeys) return;
    if (k >= seen_keys_.size()) {
      seen_keys_.resize(k + 1);
      seen_index_.resize(k + 1);
    }
    seen_keys_[k] = py::reinterpret_borrow<py::object>(key);
    seen_index_[k] = index;
  }

  // x, y, z (mm) into out_m, and a 4th value (the wire's confidence) into confidence: true
  // when it was given.
  static bool read_xyz(PyObject* value, PyObject* key, Eigen::Vector3d& out_m, double& confidence) {
    // Tuples and lists read directly; anything else (a NumPy row) through the sequence protocol.
    if (PyTuple_Check(value) || PyList_Check(value)) {
      const Py_ssize_t n = PySequence_Fast_GET_SIZE(value);
      if (n == 3 || n == 4) {
        PyObject** items = PySequence_Fast_ITEMS(value);
        for (int k = 0; k < 3; ++k) out_m[k] = item_double(items[k], key) * kMPerMm;
        if (n == 4) confidence = item_double(items[3], key);
        return n == 4;
      }
    } else if (PySequence_Check(value)) {
      const Py_ssize_t n = PySequence_Size(value);
      if (n == 3 || n == 4) {
        for (int k = 0; k < static_cast<int>(n); ++k) {
          py::object item = py::reinterpret_steal<py::object>(PySequence_GetItem(value, k));
          if (!item) throw py::error_already_set();
          const double v = item_double(item.ptr(), key);
          if (k < 3)
            out_m[k] = v * kMPerMm;
          else
            confidence = v;
        }
        return n == 4;
      }
    }
    PyErr_Clear();
    throw py::value_error("marker " + py::str(key).cast<std::string>() +
                          ": give x, y, z (3 numbers, mm) or x, y, z, confidence (0-1), not " +
                          py::repr(value).cast<std::string>());
  }

  static double item_double(PyObject* item, PyObject* key) {
    if (PyFloat_CheckExact(item)) return PyFloat_AS_DOUBLE(item);
    // True is an int to Python: read as 1 mm it hid a bug in the caller's data.
    const double v = PyBool_Check(item) ? -1.0 : PyFloat_AsDouble(item);
    if (PyBool_Check(item) || (v == -1.0 && PyErr_Occurred())) {
      PyErr_Clear();
      throw py::value_error("marker " + py::str(key).cast<std::string>() +
                            ": coordinates must be numbers (mm), as must a confidence, got " +
                            py::repr(item).cast<std::string>());
    }
    return v;
  }

  std::string unknown_name(PyObject* key) const {
    std::string names;
    for (std::size_t i = 0; i < layout_->markers && i < 8; ++i)
      names += (i ? ", " : "") + layout_->marker_names[i];
    if (layout_->markers > 8) names += ", ...";
    return py::repr(key).cast<std::string>() + " is not a marker of this tracker (" +
           std::to_string(layout_->markers) + " markers: " + names +
           "; Tracker.marker_names lists them). Pass ignore_unknown=True to skip such names";
  }

  [[noreturn]] void refuse_type(const py::handle& markers) const {
    throw py::type_error("markers: give a dict name -> (x, y, z[, confidence]) in mm, or a (" +
                         std::to_string(layout_->markers) + ", 3) or (" +
                         std::to_string(layout_->markers) +
                         ", 4) array in Tracker.marker_names order, not " +
                         std::string(py::str(py::type::of(markers).attr("__name__"))));
  }

  void read_array(const py::handle& markers) {
    // None or a number would become a 0-d array (NumPy's forcecast) and be refused for its
    // shape: the wrong type, said as such.
    if (!PySequence_Check(markers.ptr()) && !PyObject_CheckBuffer(markers.ptr()) &&
        !py::hasattr(markers, "__array__") && !py::hasattr(markers, "__array_interface__"))
      refuse_type(markers);
    auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(markers);
    if (!a) {
      // A list or array NumPy cannot read as numbers holds a coordinate that is not one: a
      // ValueError, as in a dict (docs/python.md, "Errors"); anything else is the wrong type.
      const bool array_like = (PySequence_Check(markers.ptr()) && !PyUnicode_Check(markers.ptr()) &&
                               !PyBytes_Check(markers.ptr())) ||
                              py::isinstance<py::array>(markers);
      PyErr_Clear();
      if (array_like)
        throw py::value_error(
            "markers: coordinates must be numbers (mm), in a (" + std::to_string(layout_->markers) +
            ", 3) or (" + std::to_string(layout_->markers) +
            ", 4) array in Tracker.marker_names order; this " +
            std::string(py::str(py::type::of(markers).attr("__name__"))) + " holds something else");
      refuse_type(markers);
    }
    if (a.ndim() != 2 || a.shape(0) != static_cast<py::ssize_t>(layout_->markers) ||
        (a.shape(1) != 3 && a.shape(1) != 4)) {
      std::string shape;
      for (py::ssize_t d = 0; d < a.ndim(); ++d)
        shape += (d ? ", " : "") + std::to_string(a.shape(d));
      const std::string rows = std::to_string(layout_->markers);
      throw py::value_error("markers: expected an array of shape (" + rows + ", 3) or (" + rows +
                            ", 4) (mm, then a confidence, in Tracker.marker_names order), got "
                            "shape (" +
                            shape + ")");
    }
    // A 4th column is each marker's confidence (0-1), as the wire's 4th value.
    const py::ssize_t columns = a.shape(1);
    with_confidence_ = columns == 4;
    const double* row = a.data();
    for (std::size_t i = 0; i < layout_->markers; ++i, row += columns) {
      measured_m_[i] = Eigen::Vector3d(row[0], row[1], row[2]) * kMPerMm;
      if (with_confidence_) confidence_[i] = confidence_of(row[3], measured_m_[i]);
    }
  }

  Config config_;                     // shares the loaded config
  std::unique_ptr<Tracker> tracker_;  // not movable: the result's spans point into it
  std::shared_ptr<const PoseLayout> layout_;
  std::vector<Eigen::Vector3d> measured_m_;
  std::vector<std::uint8_t> visible_;  // all 1: occlusion is NaN (or an absent name)
  std::vector<float> confidence_;      // per marker, 0-1 (1 where the input gave none)
  bool with_confidence_ = false;       // this frame gave a confidence: pass them on
  py::dict index_;                     // name -> index into the markers
  // read_dict's memory of the last dict's keys by position (-1: an ignored unknown name);
  // bounded, so a stream of ever-new names cannot grow it.
  static constexpr std::size_t kRememberedKeys = 4096;
  std::vector<py::object> seen_keys_;
  std::vector<int> seen_index_;
};

}  // namespace

void bind_tracker(py::module_& m) {
  bind_pose(m);
  py::class_<PyTracker>(m, "Tracker",
                        "fabrikd's per-frame tracking (targets, priorities, occlusion policy, "
                        "warm-started FABRIK) for one config. Not thread-safe: one thread per "
                        "Tracker.")
      .def(py::init<const Config&>(), py::arg("config"))
      .def("track", &PyTracker::track, py::arg("markers"), py::arg("time_s"),
           py::arg("ignore_unknown") = false,
           "Track one frame. markers: a dict marker name -> (x, y, z) in mm (absent names "
           "are occluded), or a (markers, 3) float array in mm in marker_names order (NaN "
           "rows are occluded). A 4th value per marker (x, y, z, confidence), or a "
           "(markers, 4) array, is its confidence (0-1, as on the daemon's wire): below the "
           "config's confidence.threshold the marker is occluded, above it scales its weight; "
           "a marker without one has confidence 1. time_s: the frame's time in seconds (the hold "
           "policy and "
           "continuity use it). Returns a Pose (a copy: it stays valid). An unknown name is a "
           "KeyError unless ignore_unknown; a wrong shape, or a coordinate that is not a number, "
           "a ValueError; anything but a dict or an array a TypeError. A solve that does not "
           "converge is a Pose.status, not an exception.")
      .def("reset", &PyTracker::reset, "Forget the previous frame: the next one starts cold")
      .def_property_readonly("config", &PyTracker::config)
      .def_property_readonly(
          "marker_names", [](const PyTracker& t) { return t.layout().marker_names; },
          "Tracked markers: the order of a track() array and of "
          "Pose.markers_mm")
      .def_property_readonly("joint_names",
                             [](const PyTracker& t) { return t.layout().joint_names; })
      .def_property_readonly("segment_names",
                             [](const PyTracker& t) { return t.layout().segment_names; })
      .def_property_readonly("coordinate_names",
                             [](const PyTracker& t) { return t.layout().coordinate_names; });
}

}  // namespace fabrik::python
