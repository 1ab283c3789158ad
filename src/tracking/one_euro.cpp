#include "one_euro.hpp"

#include <numbers>

namespace fabrik {

double one_euro_alpha(double cutoff_hz, double dt_s) {
  const double tau_s = 1.0 / (2.0 * std::numbers::pi * cutoff_hz);
  return 1.0 / (1.0 + tau_s / dt_s);
}

OneEuroFilter::OneEuroFilter(SmoothingSettings settings, int markers)
    : settings_(settings), state_(static_cast<std::size_t>(markers)), pending_(state_) {}

Eigen::Vector3d OneEuroFilter::filter(int i, double time_s, const Eigen::Vector3d& x_m) {
  const State& s = state_[i];
  State& next = pending_[i];
  const double dt_s = time_s - s.t_s;
  // A first sample, or a clock that stood still or went back: start afresh.
  if (!s.valid || !(dt_s > 0.0)) {
    next = {x_m, Eigen::Vector3d::Zero(), time_s, true};
    return x_m;
  }
  const Eigen::Vector3d dx_m_s = (x_m - s.x_m) / dt_s;
  next.dx_m_s = s.dx_m_s + one_euro_alpha(settings_.d_cutoff_hz, dt_s) * (dx_m_s - s.dx_m_s);
  const double cutoff_hz = settings_.min_cutoff_hz + settings_.beta_per_m * next.dx_m_s.norm();
  next.x_m = s.x_m + one_euro_alpha(cutoff_hz, dt_s) * (x_m - s.x_m);
  next.t_s = time_s;
  next.valid = true;
  return next.x_m;
}

void OneEuroFilter::commit(int i) {
  if (pending_[i].valid) state_[i] = pending_[i];
  pending_[i].valid = false;
}

void OneEuroFilter::reset() {
  for (State& s : state_) s.valid = false;
  for (State& s : pending_) s.valid = false;
}

}  // namespace fabrik
