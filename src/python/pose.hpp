// One tracked frame as Python sees it: a snapshot of the Tracker's result, copied once into
// the Pose's own buffers (two allocations), so it stays valid after the next track(). Its
// NumPy arrays view those buffers (no further copy) and keep the Pose alive.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "bindings.hpp"
#include "tracking/tracker.hpp"

namespace fabrik::python {

// What every pose of one tracker shares: sizes and names.
struct PoseLayout {
  std::vector<std::string> marker_names, joint_names, segment_names, coordinate_names;
  std::vector<std::uint8_t> coordinate_is_rotation;
  std::size_t markers = 0, joints = 0, segments = 0, coordinates = 0;
  // Offsets into Pose::numbers (doubles) and Pose::flags (bytes).
  std::size_t joints_at = 0, markers_at = 0, q_at = 0, origin_at = 0, coordinates_at = 0,
              residual_at = 0, numbers = 0;
  std::size_t occluded_at = 0, held_at = 0, outlier_at = 0, flags = 0;

  explicit PoseLayout(const Tracker& tracker);
};

struct Pose {
  std::shared_ptr<const PoseLayout> layout;
  double time_s = 0.0, track_us = 0.0, solve_us = 0.0;
  std::string_view status, quality;  // static strings (to_string of the enums)
  int iterations = 0, residual_count = 0, worst_marker = -1, occluded_count = 0;
  int low_confidence_count = 0;  // of occluded_count: measured, confidence below threshold
  double residual_rms_mm = 0.0, residual_max_mm = 0.0;
  bool cold_start = false;
  // joints (mm), model markers (mm), segment rotations (w, x, y, z), segment origins (mm),
  // coordinates (degrees or mm), per-marker residuals (mm, NaN when not measured).
  std::vector<double> numbers;
  std::vector<std::uint8_t> flags;  // occluded, held, outlier per marker

  Pose(std::shared_ptr<const PoseLayout> layout, double time_s, double track_us,
       const TrackResult& r);
};

void bind_pose(py::module_& m);

}  // namespace fabrik::python
