// Live rotation prediction, the segment half of live gap filling
// (gap_predictor.hpp): while some of a segment's markers are occluded, the
// segment is pulled, weakly, towards the rotation relative to its parent that
// the recent past predicts (constant angular velocity decaying to a hold), as
// an orientation target of the solver at the prediction level; a leaf segment
// with no marker seen is turned there once after the solve instead. Why: what
// is left of a segment's markers may not hold it, and the recent past is the
// best guess of where it goes. It keeps the recent past as a ring of solved
// postures, from which the marker fill (live_marker_fill.hpp) also takes
// where a segment has moved on to and the rotation that carries its occluded
// markers. Causal and allocation-free per frame.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <vector>

#include "solver/model.hpp"
#include "solver/posture.hpp"
#include "solver/solve_types.hpp"

#include "tracking/tracking_settings.hpp"

namespace fabrik {

class RotationPrediction {
 public:
  struct Past {  // one solved frame
    double time_s = 0.0;
    Posture posture;
  };

  // marker_points[i]: the model point of tracked marker i.
  RotationPrediction(const Model& model, std::span<const int> marker_points,
                     const PredictionSettings& settings);

  // One orientation target per segment that carries a tracked marker, to be
  // given to the solver (empty when prediction is off).
  const std::vector<OrientationTarget>& orientation_targets() const { return targets_; }

  // Whether time_s comes before the newest solved frame (the clock
  // restarted): the caller then forgets the past (reset) before the frame.
  bool clock_restarted(double time_s) const;

  // Before the solve of a frame: `seen` says which markers are measured now.
  // Sets the predicted rotations and their visibility (per orientation
  // target). False when it predicts nothing this frame (prediction off, or no
  // marker measured).
  bool before_solve(double time_s, std::span<const std::uint8_t> seen,
                    std::span<Eigen::Quaterniond> q_world, std::span<std::uint8_t> q_visible);

  // Right after the solve: turns each leaf segment without a measured marker
  // (which rode on its parent in the solve) to its predicted rotation
  // relative to the parent, within its joint's ranges.
  void place_leaves(Posture& posture) const;

  // The newest solved frame (nullptr before the first).
  const Past* newest() const { return started_ ? past(0) : nullptr; }

  // Where the point local_m of segment s is dt after the newest solved frame,
  // the segment moving on at its recent velocity. Needs newest().
  Eigen::Vector3d moved_on(int s, const Eigen::Vector3d& local_m, double dt) const;

  // The rotation that carries segment s's occluded markers in the solved
  // `posture` of this frame: the segment's own, or, where no marker of its own
  // holds it and its rotation was predicted, the predicted rotation relative
  // to the (solved) parent.
  Eigen::Quaterniond carrying_rotation(const Posture& posture, int s) const;

  // After the solve (and after the marker fill): keeps the solved posture.
  void record(double time_s, const Posture& posture);

  // Forget the past (the tracker starts cold).
  void reset();

 private:
  const Past* past(int age) const;  // 0: the newest, nullptr if not kept
  const Past* velocity_base() const;
  // World angular velocity (rad/s) and base velocity (m/s) of segment s over the recent past.
  void world_velocity(int s, Eigen::Vector3d& omega, Eigen::Vector3d& v) const;
  Eigen::Quaterniond relative(const Posture& posture, int s) const;
  void start_gap(int s, const Posture& posture);

  const Model& model_;
  PredictionSettings settings_;
  int n_ = 0;
  std::vector<int> marker_segment_;
  std::vector<OrientationTarget> targets_;
  std::vector<int> target_of_segment_;  // -1 if the segment carries no tracked marker

  // The recent past: a ring of solved postures.
  std::vector<Past> ring_;
  int newest_ = -1, kept_ = 0;
  bool started_ = false;

  // Per segment: in a gap since gap_start_s_, and what the prediction extrapolates.
  std::vector<std::uint8_t> in_gap_;
  std::vector<double> gap_start_s_;
  std::vector<std::uint8_t> has_history_;
  std::vector<Eigen::Quaterniond> q_rel_start_;  // relative rotation when the gap began
  std::vector<Eigen::Vector3d> omega_rel_;       // its angular velocity then (segment frame)
  std::vector<Eigen::Quaterniond> q_rel_pred_;   // this frame's predicted relative rotation
  std::vector<std::uint8_t> predicted_, segment_seen_;  // per segment, this frame
  std::vector<std::uint8_t> placed_after_;  // per segment, this frame: see place_leaves
  std::vector<std::uint8_t> leaf_;          // per segment: no child segment
};

}  // namespace fabrik
