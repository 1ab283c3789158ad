#include "synthetic_motion.hpp"
#include "random_draws.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "solver/joint_angles.hpp"

namespace fabrik {

SyntheticMotion::SyntheticMotion(const Model& model, MotionSettings settings)
    : model_(model), settings_(settings), rng_(settings.seed) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (std::size_t s = 0; s < model.segments.size(); ++s) {
    // Flexion (about the lateral axis) swings most, twist least, as in gait.
    const Eigen::Vector3d share(0.35, 0.25, 1.0);
    amplitude_rad_.emplace_back(share.cwiseProduct(draw_vector3(unit, rng_)) *
                                settings.max_swing_rad);
    phase_rad_.emplace_back(draw_vector3(unit, rng_) * 2.0 * std::numbers::pi);
  }
  q_local_.resize(model.segments.size());
}

// A limited joint swings each angle it lets move about a centre inside its
// range, never beyond it: the centre is the rest angle moved inside by the
// amplitude, the amplitude at most half the range.
Eigen::Quaterniond SyntheticMotion::limited_rotation(const Segment& seg, const Segment& parent,
                                                     const Eigen::Vector3d& amplitude_rad,
                                                     const Eigen::Vector3d& phase_rad,
                                                     double wt) const {
  const JointLimits& j = seg.joint;
  // Cardan order z, x, y; the amplitudes and phases are stored x, y, z.
  const int xyz[3] = {2, 0, 1};
  Eigen::Vector3d angles;
  for (int k = 0; k < 3; ++k) {
    const double lo = j.min_rad[k], hi = j.max_rad[k];
    const double amp = std::min(amplitude_rad[xyz[k]], 0.5 * (hi - lo));
    // lo + amp may exceed hi - amp by rounding when amp is half the range
    // (std::clamp must not be called then); this keeps clamp's result.
    const double a = lo + amp, b = hi - amp, rest = j.rest_rad[k];
    const double centre = b < a ? (rest < a ? a : b) : std::clamp(rest, a, b);
    angles[k] = centre + amp * std::sin(wt + phase_rad[xyz[k]]);
  }
  // Relative local rotation: parent anatomical * joint * child anatomical^-1.
  return parent.q_anatomical * Eigen::Quaterniond(rotation_zxy(angles)) *
         seg.q_anatomical.conjugate();
}

void SyntheticMotion::posture_at(double t_s, Posture& posture) {
  const double w = 2.0 * std::numbers::pi * settings_.frequency_hz;
  for (std::size_t s = 0; s < model_.segments.size(); ++s) {
    const Eigen::Vector3d& a = amplitude_rad_[s];
    const Eigen::Vector3d& ph = phase_rad_[s];
    if (s == 0) {
      const double yaw =
          settings_.move_root ? settings_.root_turn_rad * std::sin(0.3 * w * t_s) : 0.0;
      q_local_[s] =
          Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(0.2 * a.z() * std::sin(w * t_s + ph.z()), Eigen::Vector3d::UnitZ());
      continue;
    }
    const Segment& seg = model_.segments[s];
    if (seg.joint.limited()) {
      q_local_[s] = limited_rotation(seg, model_.segments[seg.parent], a, ph, w * t_s);
      continue;
    }
    q_local_[s] = Eigen::AngleAxisd(a.x() * std::sin(w * t_s + ph.x()), Eigen::Vector3d::UnitX()) *
                  Eigen::AngleAxisd(a.y() * std::sin(w * t_s + ph.y()), Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(a.z() * std::sin(w * t_s + ph.z()), Eigen::Vector3d::UnitZ());
  }
  Eigen::Vector3d root_m = model_.root_rest_m;
  if (settings_.move_root) {
    root_m.x() += settings_.root_travel_m * std::sin(0.25 * w * t_s);
    root_m.y() += 0.02 * std::sin(2.0 * w * t_s);  // vertical bob, twice per cycle
  }
  if (posture.segments.size() != model_.segments.size()) posture = Posture::rest(model_);
  set_from_local(model_, root_m, q_local_, posture);
}

void SyntheticMotion::sample(const Posture& posture, std::span<const int> points, double noise_m,
                             std::span<Eigen::Vector3d> out_world_m) {
  std::normal_distribution<double> noise(0.0, 1.0);
  for (std::size_t i = 0; i < points.size(); ++i) {
    out_world_m[i] = posture.point_world_m(model_, points[i]);
    if (noise_m > 0.0) out_world_m[i] += draw_vector3(noise, rng_) * noise_m;
  }
}

}  // namespace fabrik
