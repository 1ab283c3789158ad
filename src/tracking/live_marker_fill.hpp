// Live marker fill, the marker half of live gap filling (gap_predictor.hpp):
// what is reported for an occluded marker, and how a returning one's target
// goes back to its measurement. An occluded marker is reported at its model
// point plus the offset from it at which it was last measured (in its
// segment's frame, carried on the predicted rotation where no marker of its
// own holds the segment: rotation_prediction.hpp), competing with donor
// markers (as offline, donor_fill.hpp): at the start of a gap, triples of
// markers measured now are scored on the recent past (a history of measured
// frames) by how well holding the marker's coordinates in their frame would
// have predicted it, the skeleton's segment frame likewise, and the best are
// averaged by score. A marker never measured takes its model point moved by
// the mean misfit of its segment's measured markers. A marker that returns
// pulls the solve from where its model point would be (its segment moved on at
// its recent velocity, without the offset) towards its measurement at a
// bounded speed, so joint centres do not jump; the return lasts no longer than
// the marker was gone, so a pose that went wrong in a short gap is not kept.
// Causal and allocation-free per frame.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "solver/model.hpp"
#include "solver/posture.hpp"
#include "tracking/tracking_settings.hpp"

namespace fabrik {

class RotationPrediction;

// Per pair of markers (row: the filled one, [i * n + m]): whether m is on a
// segment at most max_joints joints from i's. marker_segments: each marker's segment.
std::vector<std::uint8_t> nearby_markers(const Model& model, std::span<const int> marker_segments,
                                         int max_joints);

class LiveMarkerFill {
 public:
  // marker_points[i]: the model point of tracked marker i.
  LiveMarkerFill(const Model& model, std::span<const int> marker_points,
                 const PredictionSettings& settings);

  // Before the solve of a frame, after `rotation` predicted it (its
  // before_solve returned true): for markers being handed over, moves their
  // measured targets in `target_world_m` (first marker count entries).
  void hand_over(double time_s, std::span<const std::uint8_t> seen,
                 const RotationPrediction& rotation, std::span<Eigen::Vector3d> target_world_m);

  // After the solve, before `rotation` records it: occluded markers in
  // `markers_world_m` (model positions) move by their last measured offset or
  // to their donors' fill; gap_s gets each marker's time since it was last
  // measured (0 when measured, the time since the first frame when never
  // measured). Keeps the frame's measurements for choosing donors.
  void after_solve(double time_s, const Posture& posture, const RotationPrediction& rotation,
                   std::span<const std::uint8_t> seen, std::span<const Eigen::Vector3d> measured,
                   std::span<Eigen::Vector3d> markers_world_m, std::span<double> gap_s);

  // Forget the past (the tracker starts cold).
  void reset();

 private:
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

  PredictionSettings settings_;
  int n_ = 0;
  std::vector<int> marker_segment_;
  std::vector<Eigen::Vector3d> marker_local_m_;
  double first_time_s_ = 0.0;

  // Per marker.
  std::vector<Eigen::Vector3d> offset_local_m_;  // measured minus model point, segment frame
  std::vector<std::uint8_t> has_offset_, was_seen_, ever_seen_;
  std::vector<double> last_seen_s_, previous_s_;
  std::vector<Eigen::Vector3d> latest_m_, previous_m_;  // the two latest measurements
  std::vector<std::uint8_t> has_previous_;
  std::vector<Eigen::Vector3d> handover_m_;  // target minus measurement, shrinking
  std::vector<double> handover_speed_m_per_s_;  // how fast it shrinks
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
