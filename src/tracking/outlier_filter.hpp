// Outlier markers: a measurement that disagrees with the model far beyond the other markers
// (a label swapped with another marker's, a ghost or reflection, a stray zero) is left out of
// the frame's solve, so one bad marker cannot drag the skeleton.
//
// The rule, after the frame's solve: a marker is a candidate when its residual exceeds both
// an absolute floor and a multiple of the median residual of the other measured markers
// (the bar). A candidate is an outlier only if it also moved relative to its neighbours
// (marker_neighbours.hpp): a marker the model cannot fit (a joint the model lacks) keeps
// its distances to the markers around it, and is kept. The worst such marker is left out
// and the frame solved again from the same start posture; then the next is judged the same
// way, up to `max_per_frame` markers.
// A marker far enough off can drag the whole fit with it (one of the strongest level's, e.g.
// a pelvis marker metres away): every residual is then large, the bar rises above them all
// and nothing is found. So when the solve finds none but some residual is above the floor,
// the markers are judged the same way by their distances to the start posture (the frame's
// prediction), where the others still fit; only a marker whose own residual is above the
// floor can be found so.
// Two outliers whose measurements each fit the other's model position (within the same bar)
// are a label swap: they are solved with each other's measurement (relabelled), since
// leaving a marker out loses what it alone measures (an elbow marker that places the joint).
//
// A frame that looks normal costs one pass over the residuals (no extra solve); a suspicious
// one costs one extra solve per marker left out, and one more for a swap. Nothing is
// allocated per frame.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "solver/fabrik_solver.hpp"
#include "solver/model.hpp"
#include "solver/posture.hpp"
#include "tracking/marker_neighbours.hpp"

#include "tracking/tracking_settings.hpp"

namespace fabrik {

class OutlierFilter {
 public:
  // `marker_points[i]`: the model point of the solver's target i (the first targets are the
  // markers judged).
  OutlierFilter(const Model& model, OutlierSettings settings, std::vector<int> marker_points);
  // Without a model: judged by the bar alone (no neighbour test), for tests of the bar.
  OutlierFilter(OutlierSettings settings, std::vector<int> marker_points);
  const OutlierSettings& settings() const { return settings_; }

  // Solves the frame from `start` into `posture` (with the solver's orientation
  // targets, q_world and orientation_visible: empty when it has none); then, while the worst marker is an outlier,
  // marks it (outlier[i] = 1, target_visible[i] = 0) and solves again from `start`. Swapped
  // outliers a, b get each other's measurement in target_world_m, are visible again and
  // relabelled_from[a] = b, relabelled_from[b] = a. Returns the last solve's result.
  // `outlier` must be all 0 and `relabelled_from` all -1 on entry.
  SolveResult solve(FabrikSolver& solver, const Model& model,
                    std::span<Eigen::Vector3d> target_world_m,
                    std::span<std::uint8_t> target_visible,
                    std::span<const Eigen::Quaterniond> q_world,
                    std::span<const std::uint8_t> orientation_visible, const Posture& start,
                    Posture& posture, std::span<std::uint8_t> outlier,
                    std::span<int> relabelled_from);

  // The worst marker of the last solve that is above the bar and moved relative to its
  // neighbours (`measured_m`: the markers' measurements), else -1; sets bar_m() either way
  // (when enough markers were measured). With an empty `measured_m` or no model, the worst
  // marker if it is above the bar.
  // With `residual_m` (the solve's, when judging by other distances), only a marker whose
  // residual is above the floor can be the outlier.
  int worst_outlier(std::span<const double> distances_m,
                    std::span<const std::uint8_t> target_visible,
                    std::span<const Eigen::Vector3d> measured_m = {},
                    std::span<const double> residual_m = {});
  // The residual above which a marker was an outlier in the last judgement (metres).
  double bar_m() const { return bar_m_; }

 private:
  // Relabels swapped pairs among the outliers; returns whether any was.
  bool relabel_swaps(const Model& model, const Posture& start, const Posture& posture,
                     std::span<Eigen::Vector3d> target_world_m,
                     std::span<std::uint8_t> target_visible, std::span<const std::uint8_t> outlier,
                     std::span<int> relabelled_from) const;

  OutlierSettings settings_;
  std::vector<int> marker_points_;
  int markers_;
  std::vector<double> scratch_m_;  // the other markers' residuals, for their median
  std::vector<int> found_;         // the outliers of a frame, in the order found
  // Judged against the start posture (the frame's prediction) instead of the solve: see solve().
  int worst_against_start(const Model& model, const Posture& start,
                          std::span<const Eigen::Vector3d> target_world_m,
                          std::span<const std::uint8_t> target_visible,
                          std::span<const double> residual_m);

  std::optional<MarkerNeighbours> neighbours_;
  std::vector<double> start_distances_m_;  // per marker, for worst_against_start
  double bar_m_ = 0.0;
  double largest_m_ = 0.0;  // the largest distance the last worst_outlier saw
};

}  // namespace fabrik
