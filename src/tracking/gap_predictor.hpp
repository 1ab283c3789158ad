// Live gap filling, in two parts. While some of a segment's markers are
// occluded, RotationPrediction (rotation_prediction.hpp) pulls the segment,
// weakly, towards the rotation the recent past predicts; LiveMarkerFill
// (live_marker_fill.hpp) reports each occluded marker (its last offset from
// the model, competing with donor markers) and hands a returning one over to
// its measurement at a bounded speed. The fill reads the prediction's past
// and rotations, so the order in which gap_predictor.cpp calls the two is the
// behaviour: before the solve the prediction, then the hand-over; after it
// the fill, then the posture joins the past. Causal, allocation-free per
// frame, and while every marker is seen without work beyond one posture copy
// and one history entry.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <vector>

#include "solver/model.hpp"
#include "solver/posture.hpp"
#include "solver/solve_types.hpp"

#include "tracking/live_marker_fill.hpp"
#include "tracking/rotation_prediction.hpp"
#include "tracking/tracking_settings.hpp"

namespace fabrik {

class GapPredictor {
 public:
  // marker_points[i]: the model point of tracked marker i.
  GapPredictor(const Model& model, std::span<const int> marker_points,
               const PredictionSettings& settings);

  // One orientation target per segment that carries a tracked marker, to be
  // given to the solver (empty when prediction is off).
  const std::vector<OrientationTarget>& orientation_targets() const {
    return rotation_.orientation_targets();
  }

  // Before the solve of a frame: `seen` says which markers are measured now.
  // Sets the predicted rotations and their
  // visibility (per orientation target) and, for markers being handed over,
  // moves their measured targets in `target_world_m` (first marker count entries).
  void before_solve(double time_s, std::span<const std::uint8_t> seen,
                    std::span<Eigen::Vector3d> target_world_m,
                    std::span<Eigen::Quaterniond> q_world, std::span<std::uint8_t> q_visible);

  // Right after the solve: turns each leaf segment without a measured marker
  // (which rode on its parent in the solve) to its predicted rotation
  // relative to the parent, within its joint's ranges.
  void place_leaves(Posture& posture) const { rotation_.place_leaves(posture); }

  // After the solve: occluded markers in `markers_world_m` (model positions)
  // move by their last measured offset; gap_s gets each marker's time since it
  // was last measured (0 when measured, the time since the first frame when
  // never measured).
  void after_solve(double time_s, const Posture& posture, std::span<const std::uint8_t> seen,
                   std::span<const Eigen::Vector3d> measured,
                   std::span<Eigen::Vector3d> markers_world_m, std::span<double> gap_s);

  // Forget the past (the tracker starts cold).
  void reset();

 private:
  RotationPrediction rotation_;
  LiveMarkerFill fill_;
};

}  // namespace fabrik
