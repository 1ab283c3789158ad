/// @file
/// The per-frame tracking pipeline shared by fabrikd, `fabrik solve` and the
/// benchmarks: measured markers (metres, world frame) -> targets with
/// priorities and the occlusion policy -> warm-started FABRIK -> joint
/// centres, gap-filled model markers and residuals. Solver types only: no I/O,
/// no JSON, no logging; every buffer is sized in the constructor, so track()
/// does not allocate.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "../solver/model.hpp"
#include "../solver/posture.hpp"
#include "../solver/solve_types.hpp"
#include "tracking_settings.hpp"

namespace fabrik {

class TrackerCore;

/// Everything a Tracker needs, fixed when it is made; each part has its default
/// (tracking_settings.hpp).
struct TrackerSetup {
  std::shared_ptr<const Model> model;  ///< the skeleton tracked; required
  std::vector<MarkerTarget> markers;   ///< in the order track() takes the measurements
  SolverOptions solver = tracking_solver_options();  ///< options of a warm frame's solve
  OcclusionPolicy occlusion;                         ///< what occluded markers do
  SensorSetup sensors;            ///< orientation sensors (tracking_settings.hpp); none by default
  OutlierSettings outliers;       ///< leaving out markers that do not fit
  QualitySettings quality;        ///< the bars of a good fit (TrackResult::quality)
  ColdStartSettings cold_start;   ///< how a frame without a previous one is solved
  PredictionSettings prediction;  ///< gap filling from the recent past (docs/gap-filling.md)
  ConfidenceSettings confidence;  ///< what a marker's confidence does (track() with confidence)
  SmoothingSettings smoothing;    ///< the causal filter of measured positions (docs/filtering.md)
  /// Left/right marker pairs (indices into `markers`) tested for mirrored swaps
  /// (OutlierSettings::relabel_mirrored); empty: found from the markers' names.
  std::vector<std::array<int, 2>> mirror_pairs;
};

/// The outcome of one frame. Spans stay valid until the next track() call.
struct TrackResult {
  SolveResult solve;      ///< the frame's last solve (with any outliers left out)
  double solve_us = 0.0;  ///< wall time of the solve itself
  std::span<const Eigen::Vector3d> joints_world_m;   ///< per Model::joints
  std::span<const Eigen::Vector3d> markers_world_m;  ///< per marker of the setup: model position
  std::span<const std::uint8_t> occluded;            ///< per marker: no valid measurement
  std::span<const std::uint8_t> held;                ///< per marker: occluded but held
  /// per marker: time since last measured (0 when measured, an outlier left out included;
  /// since the first frame if never, or since a frame whose time went back), across cold starts
  std::span<const double> gap_s;
  int occluded_count = 0;         ///< markers occluded in this frame
  /// Of those, markers measured but occluded by a confidence below the threshold.
  int low_confidence_count = 0;
  /// Markers relabelled before the solve as a mirrored left/right swap (their pairs are in
  /// relabelled_from too).
  int mirrored_count = 0;
  /// Residual between measured and model positions over the markers measured
  /// in this frame and solved with (held ones and outliers left out excluded), metres.
  double residual_rms_m = 0.0;
  double residual_max_m = 0.0;  ///< the largest of those residuals, metres
  int residual_count = 0;       ///< markers those residuals are over
  int worst_marker = -1;        ///< index into the setup's markers, -1 if none measured
  /// Per Model::coordinates: joint angles (radians) and translations (metres).
  /// Rotations are continuous over frames: principal values on the first frame and
  /// after reset() or a clock that went back; after that the 2 pi-equivalent nearest the
  /// last value reached by a step a body can make (a frame jumping further, as a left/right
  /// swap turns the pelvis 180 deg, is written nearest the frame before and does not move
  /// that reference for 0.5 s).
  std::span<const double> coordinates;
  /// Per segment: its anatomical frame's world rotation, and its base (origin) in the world.
  std::span<const Eigen::Quaterniond> segment_q_world;
  std::span<const Eigen::Vector3d> segment_origin_world_m;  ///< per segment: base, metres
  /// Orientation sensors, per sensor of the setup: no usable measurement in this
  /// frame; and the angle between each measured sensor's desired segment
  /// rotation and the segment's tracked one (radians, NaN when occluded).
  std::span<const std::uint8_t> sensor_occluded;
  int sensor_occluded_count = 0;             ///< sensors without a usable measurement in this frame
  std::span<const double> sensor_error_rad;  ///< per sensor: the angle above, radians
  /// RMS of those angles over the measured sensors, radians.
  double sensor_rms_rad = 0.0, sensor_max_rad = 0.0;
  /// @var sensor_max_rad
  /// The largest of those angles, radians.
  int worst_sensor = -1;  ///< index into the setup's sensors, -1 if none measured
  /// No marker pulled in this frame (orientation sensors alone): the root's
  /// position is unknown, so it was held where the previous frame left it.
  bool root_held = false;
  /// Per marker: measured, but the measurement under its label disagreed with the model far
  /// beyond the others (docs/robust-tracking.md): left out of the solve, unless relabelled_from
  /// names the marker whose measurement it was solved with instead (a label swap), else -1.
  std::span<const std::uint8_t> outliers;
  int outlier_count = 0;  ///< measured markers flagged in `outliers`
  /// Per marker: the index of the marker whose measurement it was solved with (a label swap),
  /// -1 when none.
  std::span<const int> relabelled_from;
  /// Per marker: distance between the measurement it was solved with (its own, or for an
  /// outlier left out its own) and its model position (metres); NaN when not measured.
  std::span<const double> marker_residual_m;
  /// The verdict against setup().quality, and per marker whether it was solved with and ended
  /// beyond quality.max_m.
  FitQuality quality = FitQuality::none;
  std::span<const std::uint8_t> beyond;  ///< per marker: solved with, residual beyond quality.max_m
  int beyond_count = 0;                  ///< markers flagged in `beyond`
  bool cold_start = false;               ///< this frame started cold (docs/robust-tracking.md)
};

/// The tracking pipeline of one subject (see the file's description): made once from a
/// TrackerSetup, then fed one frame at a time. Movable, not copyable.
class Tracker {
 public:
  /// Sizes every buffer. Throws std::invalid_argument when the setup does not fit together
  /// (no model, a marker without its model point, a sensor without its segment, ...) or a
  /// setting cannot run (NaN, a negative length or time, a count below its least).
  explicit Tracker(TrackerSetup setup);
  ~Tracker();
  /// The result's spans point into the tracker's state, which a move carries along. A
  /// moved-from Tracker's track() gives SolveStatus::wrong_workspace and empty spans,
  /// marker_count() 0 and reset() nothing; its setup(), model() and posture() must not be
  /// called.
  Tracker(Tracker&&) noexcept;
  /// As the move constructor: the result's spans move with the state.
  Tracker& operator=(Tracker&&) noexcept;
  Tracker(const Tracker&) = delete;
  Tracker& operator=(const Tracker&) = delete;

  const TrackerSetup& setup() const;  ///< as given to the constructor
  const Model& model() const;         ///< setup().model
  int marker_count() const;           ///< setup().markers.size()
  int sensor_count() const;           ///< setup().sensors.sensors.size()

  /// One frame: measured_world_m[i] belongs to setup().markers[i]; a marker is
  /// occluded when visible[i] is 0 or a coordinate is not finite. time_s is the
  /// frame's time (for the hold policy). Spans of the wrong size give
  /// SolveStatus::size_mismatch, and a time that is not finite SolveStatus::non_finite_input:
  /// both leave the tracker's state as it was and give a verdict of no frame
  /// (quality none, counts and residuals 0); the result's spans keep the last frame's values.
  const TrackResult& track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                           std::span<const std::uint8_t> visible);
  /// The same with orientation sensors: q_sensors_sensor[k] (sensor k's frame in
  /// the sensors' world, unit) and sensor_visible[k] belong to
  /// setup().sensors.sensors[k]; empty spans mean no sensor measured. With no
  /// marker measured or held, the root cannot be placed: it keeps its position
  /// from the previous frame (the rest position when cold) and the sensors turn
  /// the segments about it.
  const TrackResult& track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                           std::span<const std::uint8_t> visible,
                           std::span<const Eigen::Quaterniond> q_sensors_sensor,
                           std::span<const std::uint8_t> sensor_visible);

  /// The same with a confidence per marker (0-1, e.g. a keypoint's likelihood): empty means
  /// all 1; otherwise confidence[i] belongs to setup().markers[i] (another size gives
  /// SolveStatus::size_mismatch). A marker below setup().confidence.threshold is occluded;
  /// above it, its weight is scaled by its confidence (ConfidenceSettings).
  const TrackResult& track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                           std::span<const std::uint8_t> visible,
                           std::span<const Eigen::Quaterniond> q_sensors_sensor,
                           std::span<const std::uint8_t> sensor_visible,
                           std::span<const float> confidence);

  /// The same without orientation sensors.
  const TrackResult& track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                           std::span<const std::uint8_t> visible,
                           std::span<const float> confidence);

  /// Forget the previous frame: the next one starts cold (docs/robust-tracking.md).
  void reset();
  /// The posture of the last frame tracked (the rest posture before the first).
  const Posture& posture() const;

 private:
  std::unique_ptr<TrackerCore> core_;
};

}  // namespace fabrik
