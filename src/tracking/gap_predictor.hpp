// Live gap filling: while some of a segment's markers are occluded, the
// segment is pulled, weakly, towards the rotation relative to its parent that
// the recent past predicts (constant angular velocity decaying to a hold), as
// an orientation target of the solver at the prediction level. An occluded
// marker is reported at its model point plus the offset from it at which it
// was last measured (in its segment's frame), competing with donor markers
// (as offline, donor_fill.hpp): at the start of a gap, triples of markers
// measured now are scored on the recent past by how well holding the
// marker's coordinates in their frame would have predicted it, the skeleton's
// segment frame likewise, and the best are averaged by score. A marker never
// measured takes its model point moved by the mean misfit of its segment's
// measured markers. A marker that returns is handed
// over from that prediction to its measurement at a bounded speed, so joint
// centres do not jump. Causal, allocation-free per frame, and without work
// beyond one posture copy while every marker is seen.
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

// Per pair of markers (row: the filled one, [i * n + m]): whether m is on a
// segment at most max_joints joints from i's. marker_segments: each marker's segment.
std::vector<std::uint8_t> nearby_markers(const Model& model, std::span<const int> marker_segments,
                                         int max_joints);

class GapPredictor {
 public:
  // marker_points[i]: the model point of tracked marker i.
  GapPredictor(const Model& model, std::span<const int> marker_points,
               const PredictionSettings& settings);

  // One orientation target per segment that carries a tracked marker, to be
  // given to the solver (empty when prediction is off).
  const std::vector<OrientationTarget>& orientation_targets() const { return targets_; }

  // Before the solve of a frame: `seen` says which markers are measured now,
  // `last_seen_m` holds every marker's latest measurement. Sets the predicted rotations and their
  // visibility (per orientation target) and, for markers being handed over,
  // moves their measured targets in `target_world_m` (first marker count entries).
  void before_solve(double time_s, std::span<const std::uint8_t> seen,
                    std::span<Eigen::Vector3d> target_world_m,
                    std::span<Eigen::Quaterniond> q_world, std::span<std::uint8_t> q_visible);

  // Right after the solve: turns each leaf segment without a measured marker
  // (which rode on its parent in the solve) to its predicted rotation
  // relative to the parent, within its joint's ranges.
  void place_leaves(Posture& posture) const;

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
  struct Past {  // one solved frame
    double time_s = 0.0;
    Posture posture;
  };
  struct Measured {  // one frame's markers, for choosing donors
    std::vector<Eigen::Vector3d> markers_m;
    std::vector<std::uint8_t> seen;
    std::vector<Eigen::Vector3d> segment_local_m;  // each in its segment's solved frame
  };
  const Measured* measured_past(int age) const;  // 0: the newest
  struct Donors {  // one triple (a < 0: the skeleton's segment frame)
    int a = -1, b = -1, c = -1;
    Eigen::Vector3d local_m = Eigen::Vector3d::Zero();  // the marker in their frame when lost
    double score_m = 0.0;  // hold_score
    double weight = 0.0;   // 1 / max(score, floor)^2
  };
  // At the start of marker i's gap: scores triples of the markers seen now
  // (and the skeleton) on the recent past; keeps the best.
  void choose_donors(int i, std::span<const std::uint8_t> seen,
                     std::span<const Eigen::Vector3d> measured);
  // The local coordinates of marker i in a candidate's frame over the ring,
  // oldest first, and the RMS error of holding them (NaN if it cannot be scored).
  double hold_score(int i, const Donors& d);
  bool local_in(const Measured& p, int i, const Donors& d, Eigen::Vector3d& local_m) const;
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
  std::vector<Eigen::Vector3d> marker_local_m_;
  std::vector<OrientationTarget> targets_;
  std::vector<int> target_of_segment_;  // -1 if the segment carries no tracked marker

  // The recent past: a ring of solved postures.
  std::vector<Past> ring_;
  int newest_ = -1, kept_ = 0;
  double first_time_s_ = 0.0;
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

  // Per marker.
  std::vector<Eigen::Vector3d> offset_local_m_;  // measured minus model point, segment frame
  std::vector<std::uint8_t> has_offset_, was_seen_, ever_seen_;
  std::vector<double> last_seen_s_, previous_s_;
  std::vector<Eigen::Vector3d> latest_m_, previous_m_;  // the two latest measurements
  std::vector<std::uint8_t> has_previous_;
  std::vector<Eigen::Vector3d> handover_m_;  // target minus measurement, shrinking
  std::vector<std::uint8_t> handing_over_;
  std::vector<Donors> donors_;  // [i * donor_triples + t]
  std::vector<std::uint8_t> nearby_;  // nearby_markers()
  int choices_left_ = 0;        // this frame
  std::vector<Measured> history_;  // a ring, longer than the postures'
  int history_newest_ = -1, history_kept_ = 0;
  std::vector<int> donor_count_;
  std::vector<double> skeleton_score_m_;  // NaN: the skeleton does not compete
  // Scratch for choosing donors.
  std::vector<int> candidates_;
  std::vector<double> spread_m_;
  std::vector<Donors> scored_;
  std::vector<Eigen::Vector3d> series_m_;
  std::vector<std::uint8_t> series_ok_;
};

}  // namespace fabrik
