#include "target_set.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace fabrik {

TargetSet::TargetSet(const Model& model, std::vector<Target> targets,
                     const std::vector<int>& extra_levels)
    : targets_(std::move(targets)), levels_(extra_levels) {
  const int n_seg = static_cast<int>(model.segments.size());
  for (const Target& t : targets_) {
    if (t.point < 0 || t.point >= static_cast<int>(model.points.size()))
      throw std::invalid_argument("target point index out of range");
    if (!(t.weight > 0.0) || !std::isfinite(t.weight))
      throw std::invalid_argument("target weight must be positive and finite");
    levels_.push_back(t.level);
  }
  std::sort(levels_.begin(), levels_.end());
  levels_.erase(std::unique(levels_.begin(), levels_.end()), levels_.end());
  for (const Target& t : targets_) level_index_.push_back(index_of_level(t.level));

  seg_first_.assign(n_seg, 0);
  seg_count_.assign(n_seg, 0);
  for (const Target& t : targets_) ++seg_count_[model.points[t.point].segment];
  for (int s = 1; s < n_seg; ++s) seg_first_[s] = seg_first_[s - 1] + seg_count_[s - 1];
  by_segment_.assign(targets_.size(), -1);
  std::vector<int> fill(n_seg, 0);
  for (int i = 0; i < size(); ++i) {
    const int s = model.points[targets_[i].point].segment;
    by_segment_[seg_first_[s] + fill[s]++] = i;
  }
}

int TargetSet::index_of_level(int level) const {
  return static_cast<int>(std::lower_bound(levels_.begin(), levels_.end(), level) - levels_.begin());
}

SolveResult TargetSet::measure(const Model& model, const Posture& posture,
                               std::span<const Eigen::Vector3d> target_world_m,
                               std::span<const std::uint8_t> visible,
                               std::span<double> distances_m) const {
  return measure_with([&](int i) { return posture.point_world_m(model, targets_[i].point); },
                      target_world_m, visible, distances_m);
}

bool StopRule::should_stop(int iteration, std::span<const double> distances_m,
                           std::span<const double> previous_m, SolveResult& result) {
  if (result.visible_targets == 0) {
    result.status = SolveStatus::no_targets;
    return true;
  }
  if (result.max_m <= options_.tolerance_m) {
    result.status = SolveStatus::converged;
    return true;
  }
  worst_m_[checks_ % kRing] = result.max_m;
  ++checks_;
  if (iteration > 0) {
    double change_m = 0.0;
    for (std::size_t i = 0; i < distances_m.size(); ++i)
      if (!std::isnan(distances_m[i]))
        change_m = std::max(change_m, std::abs(distances_m[i] - previous_m[i]));
    double remaining_m = change_m;
    if (after_jump_) {
      after_jump_ = false;  // the first change after a jump: no rate yet
    } else if (iteration > 2 && change_m < last_change_m_) {
      const double rate = change_m / last_change_m_;
      remaining_m = change_m * rate / (1.0 - rate);
    } else if (iteration > 2) {
      remaining_m = change_m * 1e6;  // not contracting: only a tiny change itself may stop
    }
    last_change_m_ = change_m;
    if ((change_m <= options_.stall_tolerance_m || remaining_m <= options_.stall_tolerance_m) &&
        !may_still_converge(iteration, result.max_m)) {
      result.status = SolveStatus::stalled;
      return true;
    }
  }
  if (iteration >= options_.max_iterations) {
    result.status = SolveStatus::max_iterations;
    return true;
  }
  return false;
}

bool StopRule::may_still_converge(int iteration, double worst_m) const {
  // Over the last 8 checks, then the last 16: the pace of the worst distance over the newer
  // and the older half of the window. From the two paces, the fall still to come: the larger
  // of a geometric slowing down (a rate per iteration) and a power law in the iteration count
  // (power_law_fall_m), at most the pace over every iteration left. The long window sees
  // through a switch of the worst target, whose kink the short one takes for a slowing down
  // (cold stars of 50 stopped 0.1-0.3 mm short).
  const auto ago = [&](int k) { return worst_m_[(checks_ - 1 - k) % kRing]; };
  const double left = options_.max_iterations - iteration;
  for (int half : {kWindow / 2, kWindow}) {
    if (checks_ - 1 < 2 * half) return false;
    const double mid_m = ago(half);
    const double pace_m = (mid_m - worst_m) / half;
    const double older_m = (ago(2 * half) - mid_m) / half;
    if (!(pace_m > 0.0)) continue;
    double fall_m = pace_m * left;
    if (older_m > pace_m) {
      const double rate = std::pow(pace_m / older_m, 1.0 / half);
      const double geometric_m = pace_m * rate / (1.0 - rate);
      fall_m = std::min(fall_m, std::max(geometric_m, power_law_fall_m(iteration, half, pace_m,
                                                                       older_m, left)));
    }
    if (worst_m - fall_m <= options_.tolerance_m) return true;
  }
  return false;
}

double power_law_fall_m(int iteration, int half, double pace_m, double older_m, double left) {
  // The pace p(s) = pace * (s / t_new)^-b, with s the iteration and t_new, t_old the middles
  // of the window's newer and older halves; b from the two paces. Summed from `iteration`
  // over `left` iterations. Slow creep on many-effector trees (the sub-base following the
  // arms' mean pull) falls so, with the pace ~ s^-1.6: the geometric rate, constant in
  // iterations, says it stops far sooner than it does (docs/convergence.md).
  // Only a power whose sum converges (b > 1) is taken: with b <= 1 the distance would fall
  // without limit, no model of one settling; early in noisy warm frames the two paces often
  // give such a b, and taking it cost calibrated gait2354 frames 0.1 % more iterations.
  const double t = iteration, t_new = t - 0.5 * half, t_old = t - 1.5 * half;
  if (!(t_old > 0.0) || !(older_m > pace_m) || !(pace_m > 0.0) || !(left > 0.0)) return 0.0;
  const double b = std::log(older_m / pace_m) / std::log(t_new / t_old);
  if (!(b > 1.0)) return 0.0;
  const double from = t / t_new, to = (t + left) / t_new;
  return pace_m * t_new * (std::pow(from, 1.0 - b) - std::pow(to, 1.0 - b)) / (b - 1.0);
}

}  // namespace fabrik
