#include "outlier_filter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fabrik {

OutlierFilter::OutlierFilter(OutlierSettings settings, std::vector<int> marker_points)
    : settings_(settings),
      marker_points_(std::move(marker_points)),
      markers_(static_cast<int>(marker_points_.size())),
      scratch_m_(marker_points_.size()),
      start_distances_m_(marker_points_.size()) {
  found_.reserve(static_cast<std::size_t>(std::max(settings_.max_per_frame, 0)));
}

OutlierFilter::OutlierFilter(const Model& model, OutlierSettings settings,
                             std::vector<int> marker_points)
    : OutlierFilter(settings, std::move(marker_points)) {
  neighbours_.emplace(model, marker_points_);
}

int OutlierFilter::worst_outlier(std::span<const double> distances_m,
                                 std::span<const std::uint8_t> target_visible,
                                 std::span<const Eigen::Vector3d> measured_m,
                                 std::span<const double> residual_m) {
  // With residual_m, a candidate's own residual must be above the floor too.
  const auto eligible = [&](int i) {
    return residual_m.empty() || residual_m[i] > settings_.floor_m;
  };
  int worst = -1, measured = 0;
  bar_m_ = settings_.floor_m;
  for (int i = 0; i < markers_; ++i) {
    if (!target_visible[i] || !std::isfinite(distances_m[i])) continue;
    ++measured;
    if (worst < 0 || distances_m[i] > distances_m[worst]) worst = i;
  }
  largest_m_ = worst >= 0 ? distances_m[worst] : 0.0;
  if (measured < settings_.min_markers) return -1;
  std::size_t n = 0;
  for (int i = 0; i < markers_; ++i)
    if (i != worst && target_visible[i] && std::isfinite(distances_m[i]))
      scratch_m_[n++] = distances_m[i];
  const auto mid = scratch_m_.begin() + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(scratch_m_.begin(), mid, scratch_m_.begin() + static_cast<std::ptrdiff_t>(n));
  bar_m_ = std::max(settings_.floor_m, settings_.median_factor * *mid);  // upper median
  if (distances_m[worst] <= bar_m_) return -1;
  if (!neighbours_ || measured_m.empty()) return eligible(worst) ? worst : -1;
  // The worst candidate that moved; the others above the bar are fits the model lacks.
  int found = -1;
  for (int i = 0; i < markers_; ++i) {
    if (!target_visible[i] || !std::isfinite(distances_m[i]) || distances_m[i] <= bar_m_ ||
        !eligible(i))
      continue;
    if ((found < 0 || distances_m[i] > distances_m[found]) &&
        neighbours_->moved(i, measured_m.first(static_cast<std::size_t>(markers_)), target_visible,
                           settings_.moved_m))
      found = i;
  }
  return found;
}

int OutlierFilter::worst_against_start(const Model& model, const Posture& start,
                                       std::span<const Eigen::Vector3d> target_world_m,
                                       std::span<const std::uint8_t> target_visible,
                                       std::span<const double> residual_m) {
  for (int i = 0; i < markers_; ++i)
    start_distances_m_[i] =
        target_visible[i]
            ? (target_world_m[i] - start.point_world_m(model, marker_points_[i])).norm()
            : std::numeric_limits<double>::quiet_NaN();
  const double solve_bar_m = bar_m_;
  const int found = worst_outlier(start_distances_m_, target_visible, target_world_m, residual_m);
  if (found < 0) bar_m_ = solve_bar_m;  // the last judgement stays the solve's (relabel_swaps)
  return found;
}

bool OutlierFilter::relabel_swaps(const Model& model, const Posture& start,
                                  const Posture& posture,
                                  std::span<Eigen::Vector3d> target_world_m,
                                  std::span<std::uint8_t> target_visible,
                                  std::span<const std::uint8_t> outlier,
                                  std::span<int> relabelled_from) const {
  bool any = false;
  for (std::size_t x = 0; x < found_.size(); ++x) {
    const int a = found_[x];
    if (relabelled_from[a] >= 0) continue;
    for (std::size_t y = x + 1; y < found_.size(); ++y) {
      const int b = found_[y];
      if (relabelled_from[b] >= 0 || !outlier[b]) continue;
      // Each measurement fits the other's model position, in the solve that
      // left both out or in the start posture (the previous frame's): with
      // both left out, what they alone placed (an elbow) may have drifted.
      const auto fits_swapped = [&](const Posture& p) {
        const Eigen::Vector3d model_a = p.point_world_m(model, marker_points_[a]);
        const Eigen::Vector3d model_b = p.point_world_m(model, marker_points_[b]);
        return (target_world_m[a] - model_b).norm() <= bar_m_ &&
               (target_world_m[b] - model_a).norm() <= bar_m_;
      };
      if (!fits_swapped(posture) && !fits_swapped(start)) continue;
      std::swap(target_world_m[a], target_world_m[b]);
      target_visible[a] = target_visible[b] = 1;
      relabelled_from[a] = b;
      relabelled_from[b] = a;
      any = true;
      break;
    }
  }
  return any;
}

SolveResult OutlierFilter::solve(FabrikSolver& solver, const Model& model,
                                 std::span<Eigen::Vector3d> target_world_m,
                                 std::span<std::uint8_t> target_visible,
                                 std::span<const Eigen::Quaterniond> q_world,
                                 std::span<const std::uint8_t> orientation_visible,
                                 const Posture& start, Posture& posture, std::span<std::uint8_t> outlier,
                                 std::span<int> relabelled_from) {
  posture = start;  // same size: copies without allocating
  SolveResult r = solver.solve(target_world_m, target_visible, q_world, orientation_visible, posture);
  if (!settings_.enabled) return r;
  found_.clear();
  for (int k = 0; k < settings_.max_per_frame; ++k) {
    const std::span<const double> residual_m = solver.target_distances_m();
    int i = worst_outlier(residual_m, target_visible, target_world_m);
    // None found, but a residual above the floor (an outlier the bar may hide).
    if (i < 0 && largest_m_ > settings_.floor_m)
      i = worst_against_start(model, start, target_world_m, target_visible, residual_m);
    if (i < 0) break;
    outlier[i] = 1;
    target_visible[i] = 0;
    found_.push_back(i);
    posture = start;
    r = solver.solve(target_world_m, target_visible, q_world, orientation_visible, posture);
  }
  if (settings_.relabel_swaps && found_.size() >= 2 &&
      relabel_swaps(model, start, posture, target_world_m, target_visible, outlier, relabelled_from)) {
    posture = start;
    r = solver.solve(target_world_m, target_visible, q_world, orientation_visible, posture);
  }
  return r;
}

}  // namespace fabrik
