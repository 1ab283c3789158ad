// Targets indexed for the solvers: grouped by segment and by priority level,
// with the per-solve bookkeeping (distances, convergence) both solver
// families share. Everything is sized once, at construction.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "model.hpp"
#include "posture.hpp"
#include "solve_types.hpp"

namespace fabrik {

class TargetSet {
 public:
  // `extra_levels`: levels of other kinds of targets (orientation targets)
  // that take part in the priority loop too.
  TargetSet(const Model& model, std::vector<Target> targets,
            const std::vector<int>& extra_levels = {});

  const std::vector<Target>& targets() const { return targets_; }
  int size() const { return static_cast<int>(targets_.size()); }
  // Distinct levels, weakest first.
  const std::vector<int>& levels() const { return levels_; }
  int level_index(int target) const { return level_index_[target]; }
  // Index of a level value in levels().
  int index_of_level(int level) const;
  // Targets on segment s: ids()[first, first + count).
  std::span<const int> on_segment(int s) const {
    return {by_segment_.data() + seg_first_[s], static_cast<std::size_t>(seg_count_[s])};
  }

  // Distance of every target to its point (NaN for invisible ones) and the
  // summary over visible ones.
  SolveResult measure(const Model& model, const Posture& posture,
                      std::span<const Eigen::Vector3d> target_world_m,
                      std::span<const std::uint8_t> visible, std::span<double> distances_m) const;
  // The same, with the world position of target i's point given by point_of(i)
  // (a solver that keeps some points outside the posture during a solve).
  template <class PointOf>
  SolveResult measure_with(PointOf point_of, std::span<const Eigen::Vector3d> target_world_m,
                           std::span<const std::uint8_t> visible,
                           std::span<double> distances_m) const;

 private:
  std::vector<Target> targets_;
  std::vector<int> levels_;
  std::vector<int> level_index_;
  std::vector<int> by_segment_;
  std::vector<int> seg_first_, seg_count_;
};

template <class PointOf>
SolveResult TargetSet::measure_with(PointOf point_of,
                                    std::span<const Eigen::Vector3d> target_world_m,
                                    std::span<const std::uint8_t> visible,
                                    std::span<double> distances_m) const {
  SolveResult r;
  double sum_sq = 0.0;
  for (int i = 0; i < size(); ++i) {
    if (!visible[i]) {
      distances_m[i] = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    const double d = (point_of(i) - target_world_m[i]).norm();
    distances_m[i] = d;
    sum_sq += d * d;
    ++r.visible_targets;
    if (d > r.max_m || r.worst_target < 0) {
      r.max_m = d;
      r.worst_target = i;
    }
  }
  if (r.visible_targets > 0) r.rms_m = std::sqrt(sum_sq / r.visible_targets);
  return r;
}

// How far a distance falling at `pace_m` an iteration over the newer half of a window of
// 2 * `half` checks ending at `iteration`, and at `older_m` over the older half, falls in
// the `left` iterations to come, its pace shrinking as a power of the iteration count.
double power_law_fall_m(int iteration, int half, double pace_m, double older_m, double left);

// The per-iteration stopping rules shared by all iterative solvers: within
// tolerance; stalled; out of iterations. A solve is stalled when the target
// distances will change by less than the stall tolerance from now on, as
// estimated from the last two changes assuming linear (geometric)
// convergence: remaining = change * rate / (1 - rate). A fast solver stops
// soon after it has converged, a slowly creeping one keeps going.
// That estimate is held back while the solve may still meet the tolerance:
// when the worst distance, falling on as it fell over the last 8 checks, or
// over the last 16 (geometrically at the rate of the window's two halves, or as
// a power of the iteration count, whichever falls further, at most linearly over
// the iterations left), would reach the tolerance. On a
// tree of many end effectors the arms settle fast and the sub-base creeps: the
// fast mode's rate predicted no change left, and stars of 20-50 stopped up to
// 17 % of their solves 0.1-0.5 mm short (docs/convergence.md). Out of reach,
// or on noisy markers, the worst distance stays far above the tolerance or
// stops falling: such solves stop as early as before.
class StopRule {
 public:
  explicit StopRule(const SolverOptions& options) : options_(options) {}
  // Returns true (and sets result.status) when the solve should stop.
  bool should_stop(int iteration, std::span<const double> distances_m,
                   std::span<const double> previous_m, SolveResult& result);
  // The posture jumped after the last check (SolverOptions::extrapolate): the next check
  // judges the change alone, without a contraction rate.
  void jumped() { after_jump_ = true; }

 private:
  // Whether the worst distance, at its pace over the last checks (the ring), would reach the
  // tolerance in the iterations left after `iteration`.
  bool may_still_converge(int iteration, double worst_m) const;

  static constexpr int kWindow = 8;  // the short window; the long one is twice as long
  static constexpr int kRing = 32;   // holds the long window (2 * kWindow checks back)
  const SolverOptions& options_;
  double last_change_m_ = 0.0;
  bool after_jump_ = false;
  std::array<double, kRing> worst_m_{};  // ring: the worst distance at the last checks
  int checks_ = 0;
};

// SolverOptions::fallback_carry's trigger: whether a solve's loop is leaving a fit it has
// nearly reached. Fed the RMS at the start and after each iteration, it says diverging once
// the RMS has risen kRises iterations in a row to over kFactor times its lowest this solve,
// with some target still beyond the tolerance. A cold start's RMS also rises now and then as
// the posture unfolds, but not for iterations on end.
class DivergenceWatch {
 public:
  static constexpr int kRises = 4;
  static constexpr double kFactor = 1.25;
  explicit DivergenceWatch(double start_rms_m) : lowest_m_(start_rms_m), previous_m_(start_rms_m) {}
  bool diverging(double rms_m, double max_m, double tolerance_m) {
    rises_ = rms_m > previous_m_ ? rises_ + 1 : 0;
    const bool out = max_m > tolerance_m && rises_ >= kRises && rms_m > kFactor * lowest_m_;
    previous_m_ = rms_m;
    lowest_m_ = std::min(lowest_m_, rms_m);
    return out;
  }

 private:
  double lowest_m_, previous_m_;
  int rises_ = 0;  // iterations in a row whose RMS rose
};

}  // namespace fabrik
