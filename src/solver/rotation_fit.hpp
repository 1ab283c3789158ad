// Rotation fitting used by the segment update rules. Both functions are
// allocation-free and warm-started from the current rotation.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace fabrik {

// The minimal rotation taking direction `from` onto direction `to`, applied
// after `q`: the paper's rule (rotate in the plane of a and b by their angle).
// Returns `q` unchanged when either vector is too short to define a direction.
inline Eigen::Quaterniond rotate_minimal(const Eigen::Quaterniond& q, const Eigen::Vector3d& from,
                                         const Eigen::Vector3d& to) {
  constexpr double kMinLength = 1e-12;
  if (from.squaredNorm() < kMinLength * kMinLength || to.squaredNorm() < kMinLength * kMinLength)
    return q;
  return (Eigen::Quaterniond::FromTwoVectors(from, to) * q).normalized();
}

// Least-squares rotation: the R maximising trace(R^T A), where
// A = sum_k w_k b_k a_k^T pairs local vectors a_k with desired world vectors b_k.
// Iterative quaternion extraction after Mueller, Bender, Chentanez & Macklin,
// "A Robust Method to Extract the Rotational Part of Deformations" (MIG 2016):
// starting from the current rotation it needs a few cheap steps per call and,
// when A is rank-deficient (one or two collinear points), it stops at the
// rotation nearest the start, i.e. it adds no spurious twist.
inline Eigen::Quaterniond fit_rotation(const Eigen::Matrix3d& a, Eigen::Quaterniond q,
                                       int max_steps = 16) {
  constexpr double kAngleTolRad = 1e-12;
  constexpr double kMaxStepRad = 1.0;
  for (int step = 0; step < max_steps; ++step) {
    const Eigen::Matrix3d r = q.toRotationMatrix();
    const Eigen::Vector3d torque =
        r.col(0).cross(a.col(0)) + r.col(1).cross(a.col(1)) + r.col(2).cross(a.col(2));
    const double scale =
        std::abs(r.col(0).dot(a.col(0)) + r.col(1).dot(a.col(1)) + r.col(2).dot(a.col(2)));
    // The step is torque / stiffness; near 90 degrees from the optimum the
    // stiffness vanishes, so the step is capped rather than allowed to blow up.
    const Eigen::Vector3d omega = torque / (scale + 1e-9 * a.norm() + 1e-300);
    const double angle_rad = omega.norm();
    if (!(angle_rad > kAngleTolRad)) break;  // also stops on NaN
    const double step_rad = std::min(angle_rad, kMaxStepRad);
    q = (Eigen::Quaterniond(Eigen::AngleAxisd(step_rad, omega / angle_rad)) * q).normalized();
  }
  return q;
}

}  // namespace fabrik
