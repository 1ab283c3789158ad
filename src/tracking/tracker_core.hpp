// The Tracker's state and frame pipeline (tracker.hpp is the public face: a Tracker owns one
// TrackerCore, so the solver, filters and scratch buffers below stay out of the public headers).
#pragma once

#include "gap_predictor.hpp"
#include "solver/fabrik_solver.hpp"
#include "solver/model.hpp"
#include "solver/posture.hpp"
#include "solver/warm_start.hpp"
#include "tracking/cold_start.hpp"
#include "tracking/coordinate_branch.hpp"
#include "tracking/fit_quality.hpp"
#include "tracking/mirror_swap.hpp"
#include "tracking/one_euro.hpp"
#include "tracking/outlier_filter.hpp"
#include "tracking/sensor_targets.hpp"
#include "tracking/tracker.hpp"

namespace fabrik {

class TrackerCore {
 public:
  explicit TrackerCore(TrackerSetup setup);
  // The result's spans point into this object: it is neither copied nor moved.
  TrackerCore(const TrackerCore&) = delete;
  TrackerCore& operator=(const TrackerCore&) = delete;

  const TrackerSetup& setup() const { return setup_; }
  const Model& model() const { return *setup_.model; }
  int marker_count() const { return static_cast<int>(setup_.markers.size()); }
  int sensor_count() const { return sensors_.size(); }

  // The members below are Tracker's (tracker.hpp documents them).
  const TrackResult& track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                           std::span<const std::uint8_t> visible);
  const TrackResult& track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                           std::span<const std::uint8_t> visible,
                           std::span<const Eigen::Quaterniond> q_sensors_sensor,
                           std::span<const std::uint8_t> sensor_visible,
                           std::span<const float> confidence = {});

  void reset();
  const Posture& posture() const { return posture_; }

 private:
  // A frame refused before its solve gives no verdict: its counts, residuals and quality are
  // those of no frame, not the previous one's (the spans keep the posture's values).
  void clear_verdict();

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
  std::vector<double> coordinates_now_;  // this frame's, before they are put on their branch
  bool coordinates_continue_ = false;    // the coordinates continue the previous frame's
  std::vector<Eigen::Quaterniond> segment_q_;
  std::vector<Eigen::Vector3d> segment_origin_m_;
  std::vector<std::uint8_t> occluded_, held_, outlier_, beyond_;
  std::vector<double> marker_residual_m_;
  std::vector<int> relabelled_from_;
  // The solver's orientation targets: the sensors', then the predictor's.
  std::vector<Eigen::Quaterniond> orient_q_world_;
  std::vector<std::uint8_t> orient_visible_;
  std::vector<double> gap_s_;
  // A marker's gap age, kept here and not by the predictor (which starts afresh at a cold
  // start): the time it was last measured, and where the clock began (the first frame, or
  // one whose time went back: a new recording). NaN: no frame yet.
  std::vector<double> last_measured_s_;
  double clock_start_s_ = NAN, last_time_s_ = NAN;
  std::vector<std::uint8_t> measured_;  // per marker, this frame (outliers included)
  MirrorSwap mirror_;
  OneEuroFilter smoother_;
  CoordinateBranch branch_;                  // which whole turn each rotation is written on
  std::vector<double> weight_scale_;         // per solver target: the markers' confidences, then 1
  std::vector<Eigen::Vector3d> input_m_;     // [n_]: measured, mirrored swaps undone, unfiltered
  std::vector<Eigen::Vector3d> predicted_m_;  // [n_]: each marker's point in the warm start
  TrackResult result_;
};

}  // namespace fabrik
