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
  const double norms = std::sqrt(from.squaredNorm() * to.squaredNorm());
  if (norms < kMinLength * kMinLength) return q;
  // Half-angle form: (|a||b| + a.b, a x b) is the rotation by angle(a, b),
  // unnormalised; one square root instead of Eigen's three.
  const double w = norms + from.dot(to);
  if (w < 1e-12 * norms) return (Eigen::Quaterniond::FromTwoVectors(from, to) * q).normalized();
  const Eigen::Vector3d axis = from.cross(to);
  return (Eigen::Quaterniond(w, axis.x(), axis.y(), axis.z()) * q).normalized();
}

// Least-squares rotation: the R maximising f(R) = trace(R^T A), where
// A = sum_k w_k b_k a_k^T pairs local vectors a_k with desired world vectors b_k.
// Newton's method on the rotation, warm-started from the current one: with
// M = A R^T, the gradient of f under a small world rotation w is the torque
// vex(M - M^T) and its Hessian is -(trace(M) I - sym(M)). Mueller et al.
// ("A Robust Method to Extract the Rotational Part of Deformations", MIG
// 2016) keep only the trace(M) I term, which converges slowly when A is
// ill-conditioned (two drivers, a flat marker cluster); the full Hessian
// converges in a few steps. When A is rank-deficient the Hessian is singular
// about the undetermined axis, where the torque is zero too: the result is
// the rotation nearest the start, with no spurious twist.
// `r` is q as a matrix (callers have it cached).
inline Eigen::Quaterniond fit_rotation(const Eigen::Matrix3d& a, Eigen::Quaterniond q,
                                       Eigen::Matrix3d r, int max_steps = 12) {
  constexpr double kAngleTolRad = 1e-12;
  constexpr double kMaxStepRad = 1.0;  // the exponential below relies on it being <= 1
  for (int step = 0; step < max_steps; ++step) {
    if (step > 0) r = q.toRotationMatrix();
    const Eigen::Matrix3d m = a * r.transpose();
    const Eigen::Vector3d torque(m(2, 1) - m(1, 2), m(0, 2) - m(2, 0), m(1, 0) - m(0, 1));
    const double trace = m.trace();
    // h = trace I - sym(m), solved by its adjugate (symmetric 3x3).
    const double h00 = trace - m(0, 0), h11 = trace - m(1, 1), h22 = trace - m(2, 2);
    const double h01 = -0.5 * (m(0, 1) + m(1, 0)), h02 = -0.5 * (m(0, 2) + m(2, 0));
    const double h12 = -0.5 * (m(1, 2) + m(2, 1));
    const double c00 = h11 * h22 - h12 * h12, c01 = h02 * h12 - h01 * h22,
                 c02 = h01 * h12 - h02 * h11;
    const double det = h00 * c00 + h01 * c01 + h02 * c02;
    Eigen::Vector3d omega;
    if (trace > 0.0 && h00 > 0.0 && h00 * h11 - h01 * h01 > 0.0 &&
        det > 1e-18 * trace * trace * trace) {
      const double c11 = h00 * h22 - h02 * h02, c12 = h01 * h02 - h00 * h12,
                   c22 = h00 * h11 - h01 * h01;
      omega = Eigen::Vector3d(c00 * torque.x() + c01 * torque.y() + c02 * torque.z(),
                              c01 * torque.x() + c11 * torque.y() + c12 * torque.z(),
                              c02 * torque.x() + c12 * torque.y() + c22 * torque.z()) /
              det;  // Newton step
    } else {
      omega =
          torque / (std::abs(trace) + 1e-9 * a.norm() + 1e-300);  // far or singular: gradient step
    }
    const double angle_rad = omega.norm();
    if (!(angle_rad > kAngleTolRad)) break;  // also stops on NaN
    if (angle_rad > kMaxStepRad) omega *= kMaxStepRad / angle_rad;
    // Exact exponential of the step, without trigonometric calls: the half
    // angle is at most kMaxStepRad / 2 = 0.5, where these Taylor series of
    // cos(h) and sin(h)/h are exact to 1e-12 (and the result is normalised).
    const double h2 = 0.25 * omega.squaredNorm();
    const double cos_half =
        1.0 +
        h2 * (-1.0 / 2 + h2 * (1.0 / 24 + h2 * (-1.0 / 720 + h2 * (1.0 / 40320 - h2 / 3628800.0))));
    const double sinc_half =
        1.0 + h2 * (-1.0 / 6 +
                    h2 * (1.0 / 120 + h2 * (-1.0 / 5040 + h2 * (1.0 / 362880 - h2 / 39916800.0))));
    const Eigen::Quaterniond turn(cos_half, 0.5 * sinc_half * omega.x(),
                                  0.5 * sinc_half * omega.y(), 0.5 * sinc_half * omega.z());
    q = (turn * q).normalized();
    if (angle_rad < 1e-8) break;  // quadratic convergence: the next step would be negligible
  }
  return q;
}

}  // namespace fabrik
