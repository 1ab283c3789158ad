// The per-frame tracking pipeline shared by fabrikd, `fabrik solve` and the
// benchmarks: measured markers (metres, world frame) -> targets with
// priorities and the occlusion policy -> warm-started FABRIK -> joint
// centres, gap-filled model markers and residuals. Solver types only: no I/O,
// no JSON, no logging; every buffer is sized in the constructor, so track()
// does not allocate.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "gap_predictor.hpp"
#include "solver/fabrik_solver.hpp"
#include "solver/model.hpp"
#include "solver/posture.hpp"
#include "solver/warm_start.hpp"
#include "tracking/sensor_targets.hpp"
#include "tracking/cold_start.hpp"
#include "tracking/fit_quality.hpp"
#include "tracking/outlier_filter.hpp"

namespace fabrik {

// A named measured marker that pulls one model point.
struct MarkerTarget {
  std::string marker;  // name in the marker stream
  int point = -1;      // index into Model::points
  int level = 0;       // priority level, higher is stronger
  double weight = 1.0;
};

struct OcclusionPolicy {
  // An occluded marker's last measured position keeps pulling its point for
  // this long, as a target of `hold_level`; 0 turns holding off.
  double hold_s = 0.0;
  int hold_level = -1;
};

struct TrackerSetup {
  std::shared_ptr<const Model> model;
  std::vector<MarkerTarget> markers;
  SolverOptions solver;
  OcclusionPolicy occlusion;
  SensorSetup sensors;  // orientation sensors (sensor_targets.hpp); none by default
  OutlierSettings outliers;
  QualitySettings quality;
  ColdStartSettings cold_start;
  PredictionSettings prediction;  // gap filling from the recent past (gap_predictor.hpp)
};

// The outcome of one frame. Spans stay valid until the next track() call.
struct TrackResult {
  SolveResult solve;
  double solve_us = 0.0;                             // wall time of the solve itself
  std::span<const Eigen::Vector3d> joints_world_m;   // per Model::joints
  std::span<const Eigen::Vector3d> markers_world_m;  // per marker of the setup: model position
  std::span<const std::uint8_t> occluded;            // per marker: no valid measurement
  std::span<const std::uint8_t> held;                // per marker: occluded but held
  std::span<const double> gap_s;  // per marker: time since last measured (0 when measured)
  int occluded_count = 0;
  // Residual between measured and model positions over the markers measured
  // in this frame and solved with (held ones and outliers left out excluded), metres.
  double residual_rms_m = 0.0;
  double residual_max_m = 0.0;
  int residual_count = 0;
  int worst_marker = -1;  // index into the setup's markers, -1 if none measured
  // Per Model::coordinates: joint angles (radians) and translations (metres).
  // Rotations are continuous over frames (unwrap_coordinates, joint_angles.hpp):
  // principal values on the first frame and after reset() or a clock that went
  // back, the 2 pi-equivalent nearest the previous frame's value after that.
  std::span<const double> coordinates;
  // Per segment: its anatomical frame's world rotation, and its base (origin) in the world.
  std::span<const Eigen::Quaterniond> segment_q_world;
  std::span<const Eigen::Vector3d> segment_origin_world_m;
  // Orientation sensors, per sensor of the setup: no usable measurement in this
  // frame; and the angle between each measured sensor's desired segment
  // rotation and the segment's tracked one (radians, NaN when occluded).
  std::span<const std::uint8_t> sensor_occluded;
  int sensor_occluded_count = 0;
  std::span<const double> sensor_error_rad;
  double sensor_rms_rad = 0.0, sensor_max_rad = 0.0;
  int worst_sensor = -1;  // index into the setup's sensors, -1 if none measured
  // No marker pulled in this frame (orientation sensors alone): the root's
  // position is unknown, so it was held where the previous frame left it.
  bool root_held = false;
  // Per marker: measured, but the measurement under its label disagreed with the model far
  // beyond the others (outlier_filter.hpp): left out of the solve, unless relabelled_from
  // names the marker whose measurement it was solved with instead (a label swap), else -1.
  std::span<const std::uint8_t> outliers;
  int outlier_count = 0;
  std::span<const int> relabelled_from;
  // Per marker: distance between the measurement it was solved with (its own, or for an
  // outlier left out its own) and its model position (metres); NaN when not measured.
  std::span<const double> marker_residual_m;
  // The verdict against setup().quality, and per marker whether it was solved with and ended
  // beyond quality.max_m.
  FitQuality quality = FitQuality::none;
  std::span<const std::uint8_t> beyond;
  int beyond_count = 0;
  bool cold_start = false;  // this frame started cold (cold_start.hpp)
};

class Tracker {
 public:
  explicit Tracker(TrackerSetup setup);
  // The result's spans point into this object: it is neither copied nor moved.
  Tracker(const Tracker&) = delete;
  Tracker& operator=(const Tracker&) = delete;

  const TrackerSetup& setup() const { return setup_; }
  const Model& model() const { return *setup_.model; }
  int marker_count() const { return static_cast<int>(setup_.markers.size()); }
  int sensor_count() const { return sensors_.size(); }

  // One frame: measured_world_m[i] belongs to setup().markers[i]; a marker is
  // occluded when visible[i] is 0 or a coordinate is not finite. time_s is the
  // frame's time (for the hold policy). Spans of the wrong size give
  // SolveStatus::size_mismatch and leave the posture as it was.
  const TrackResult& track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                           std::span<const std::uint8_t> visible);
  // The same with orientation sensors: q_sensors_sensor[k] (sensor k's frame in
  // the sensors' world, unit) and sensor_visible[k] belong to
  // setup().sensors.sensors[k]; empty spans mean no sensor measured. With no
  // marker measured or held, the root cannot be placed: it keeps its position
  // from the previous frame (the rest position when cold) and the sensors turn
  // the segments about it.
  const TrackResult& track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                           std::span<const std::uint8_t> visible,
                           std::span<const Eigen::Quaterniond> q_sensors_sensor,
                           std::span<const std::uint8_t> sensor_visible);

  // Forget the previous frame: the next one starts cold (cold_start.hpp).
  void reset();
  const Posture& posture() const { return posture_; }

 private:
  TrackerSetup setup_;
  SensorTargets sensors_;  // before solver_: its targets are the solver's
  GapPredictor predictor_;  // before solver_: its targets follow the sensors'
  FabrikSolver solver_;
  Posture rest_;  // the cold start
  Posture posture_;
  bool warm_ = false;
  double last_solved_s_ = 0.0;  // time of the last frame with a measured marker
  SolverOptions cold_options_;
  OutlierFilter outliers_;
  Posture start_;  // the frame's start posture, for the outlier filter's re-solves
  WarmStart warm_start_;  // where start_ comes from on a warm frame
  std::vector<int> marker_points_;
  int n_ = 0;                                    // markers
  std::vector<Eigen::Vector3d> target_world_m_;  // [n_]: measured, [n_, 2n_): held
  std::vector<std::uint8_t> target_visible_;
  std::vector<Eigen::Vector3d> last_seen_m_;
  std::vector<double> last_seen_s_;
  std::vector<Eigen::Vector3d> joints_m_, markers_m_;
  std::vector<double> coordinates_;
  std::vector<double> coordinates_now_;  // this frame's, before they are unwrapped
  bool coordinates_continue_ = false;    // coordinates_ holds the previous frame's
  std::vector<Eigen::Quaterniond> segment_q_;
  std::vector<Eigen::Vector3d> segment_origin_m_;
  std::vector<std::uint8_t> occluded_, held_, outlier_, beyond_;
  std::vector<double> marker_residual_m_;
  std::vector<int> relabelled_from_;
  // The solver's orientation targets: the sensors', then the predictor's.
  std::vector<Eigen::Quaterniond> orient_q_world_;
  std::vector<std::uint8_t> orient_visible_;
  std::vector<double> gap_s_;
  std::vector<std::uint8_t> measured_;  // per marker, this frame (outliers included)
  TrackResult result_;
};

}  // namespace fabrik
