// Live gap filling: while some of a segment's markers are occluded, the
// segment is pulled, weakly, towards the rotation relative to its parent that
// the recent past predicts (constant angular velocity decaying to a hold), as
// an orientation target of the solver at the prediction level; an occluded
// marker is reported at its model point plus the offset from it at which it
// was last measured (in its segment's frame); a marker that returns is handed
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

namespace fabrik {

struct PredictionSettings {
  bool enabled = false;
  // Priority level and weight of the predicted rotations (orientation
  // targets). The daemon config puts them on the weakest marker level with
  // weight 0.05: a pull that markers on the same level outweigh, which takes
  // no extra priority pass (a level of their own below the markers' costs one
  // and, where markers of children constrain the segment, leaves it nothing).
  int level = 0;
  double weight = 0.05;
  // The relative angular velocity at the start of a gap decays with this time
  // constant, so the prediction turns at most velocity * decay and then holds
  // (0: hold from the start).
  double velocity_decay_s = 0.1;
  // Velocities are differences over this much of the recent past (at least
  // one frame): long enough to average marker noise, short enough to follow.
  double velocity_window_s = 0.05;
  // A returning marker's target moves from where the prediction had it to
  // its measurement at most this fast, so the posture does not jump.
  double return_speed_m_per_s = 0.2;
};

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

  // Per marker.
  std::vector<Eigen::Vector3d> offset_local_m_;  // measured minus model point, segment frame
  std::vector<std::uint8_t> has_offset_, was_seen_, ever_seen_;
  std::vector<double> last_seen_s_, previous_s_;
  std::vector<Eigen::Vector3d> latest_m_, previous_m_;  // the two latest measurements
  std::vector<std::uint8_t> has_previous_;
  std::vector<Eigen::Vector3d> handover_m_;  // target minus measurement, shrinking
  std::vector<std::uint8_t> handing_over_;
};

}  // namespace fabrik
