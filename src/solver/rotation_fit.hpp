// Rotation updates used by the segment rules: the paper's minimal turn and
// one Newton step of the least-squares rotation fit. Allocation-free, in
// place, warm-started from the current rotation.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "posture.hpp"

namespace fabrik {

// In-place, scalar forms for the solver's inner loop (each segment visit):
// no temporaries, one square root per normalisation, and the cached matrix
// rebuilt once.

// pose.q <- normalise(p * pose.q) for an unnormalised p = (pw, px, py, pz),
// and pose.r <- its matrix. The matrix is built from u = p * q itself,
// scaled by 2 / |u|^2 (exact for any non-zero u), and |u|^2 = |p|^2 |q|^2
// needs no wait for the product: the next segment reads only the matrix, so
// its chain of dependent operations holds one division instead of the
// product's norm, a square root and a division. |q|^2 is kept (not assumed
// 1) so rounding cannot build up over a long stream.
inline void premultiply_rotation(double pw, double px, double py, double pz, SegmentPose& pose) {
  const double qw = pose.q_world.w(), qx = pose.q_world.x(), qy = pose.q_world.y(),
               qz = pose.q_world.z();
  const double w = pw * qw - px * qx - py * qy - pz * qz;
  const double x = pw * qx + px * qw + py * qz - pz * qy;
  const double y = pw * qy - px * qz + py * qw + pz * qx;
  const double z = pw * qz + px * qy - py * qx + pz * qw;
  const double u_sq =
      (pw * pw + px * px + py * py + pz * pz) * (qw * qw + qx * qx + qy * qy + qz * qz);
  const double s = 2.0 / u_sq;
  const double tx = s * x, ty = s * y, tz = s * z;
  const double twx = tx * w, twy = ty * w, twz = tz * w;
  const double txx = tx * x, txy = ty * x, txz = tz * x;
  const double tyy = ty * y, tyz = tz * y, tzz = tz * z;
  Eigen::Matrix3d& r = pose.r_world;
  r(0, 0) = 1 - (tyy + tzz);
  r(0, 1) = txy - twz;
  r(0, 2) = txz + twy;
  r(1, 0) = txy + twz;
  r(1, 1) = 1 - (txx + tzz);
  r(1, 2) = tyz - twx;
  r(2, 0) = txz - twy;
  r(2, 1) = tyz + twx;
  r(2, 2) = 1 - (txx + tyy);
  const double inv = 1.0 / std::sqrt(u_sq);
  pose.q_world = Eigen::Quaterniond(w * inv, x * inv, y * inv, z * inv);
}

// The paper's rule, in place: the minimal rotation (in the plane of the two
// directions, by their angle) that turns world direction `from` onto `to`.
inline void turn_minimal(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                         SegmentPose& pose) {
  const double fx = from.x(), fy = from.y(), fz = from.z(), tx = to.x(), ty = to.y(), tz = to.z();
  const double norms = std::sqrt((fx * fx + fy * fy + fz * fz) * (tx * tx + ty * ty + tz * tz));
  if (norms < 1e-24) return;
  const double w = norms + fx * tx + fy * ty + fz * tz;
  if (w < 1e-12 * norms) {  // opposite directions: any half turn; rare, take Eigen's
    pose.set_unit_rotation(
        (Eigen::Quaterniond::FromTwoVectors(from, to) * pose.q_world).normalized());
    return;
  }
  premultiply_rotation(w, fy * tz - fz * ty, fz * tx - fx * tz, fx * ty - fy * tx, pose);
}

// Least-squares rotation: the R maximising f(R) = trace(R^T A), where
// A = sum_k w_k b_k a_k^T pairs local vectors a_k with desired world vectors b_k.
// Newton's method on the rotation, warm-started from the current one: with
// M = A R^T, the gradient of f under a small world rotation w is the torque
// vex(M - M^T) and its Hessian is -(trace(M) I - sym(M)). Mueller et al.
// ("A Robust Method to Extract the Rotational Part of Deformations", MIG
// 2016) keep only the trace(M) I term, which converges slowly when A is
// ill-conditioned (two drivers, a flat marker cluster); the full Hessian
// converges in a few steps. When A is rank-deficient (two drivers about
// their mean) the Hessian is singular about the undetermined axis, where the
// torque is zero too; but near the fit its determinant there is rounding
// noise of either sign, and a Newton step through it turns the segment about
// that axis by up to the 1 rad cap. So Newton is taken only where the
// Hessian's smallest eigenvalue is clearly above rounding (det > 1e-9
// trace^3: points near a line are off it by over about 3e-5 of their spread);
// elsewhere the gradient step, which has no component along that axis, keeps
// the rotation nearest the start.
//
// One Newton step, in place, from m = A R^T = sum_k w_k b_k (R a_k)^T, the
// desired world vectors against where the current rotation puts the local
// ones (built by the caller from world vectors: fewer dependent operations
// than forming A and then the product).
inline void fit_rotation_step(const Eigen::Matrix3d& m, SegmentPose& pose) {
  const double t0 = m(2, 1) - m(1, 2), t1 = m(0, 2) - m(2, 0), t2 = m(1, 0) - m(0, 1);
  const double trace = m(0, 0) + m(1, 1) + m(2, 2);
  const double h00 = trace - m(0, 0), h11 = trace - m(1, 1), h22 = trace - m(2, 2);
  const double h01 = -0.5 * (m(0, 1) + m(1, 0)), h02 = -0.5 * (m(0, 2) + m(2, 0));
  const double h12 = -0.5 * (m(1, 2) + m(2, 1));
  const double c00 = h11 * h22 - h12 * h12, c01 = h02 * h12 - h01 * h22,
               c02 = h01 * h12 - h02 * h11;
  const double det = h00 * c00 + h01 * c01 + h02 * c02;
  double ox, oy, oz, scale;  // the step is (ox, oy, oz) / scale
  if (trace > 0.0 && h00 > 0.0 && h00 * h11 - h01 * h01 > 0.0 &&
      det > 1e-9 * trace * trace * trace) {
    const double c11 = h00 * h22 - h02 * h02, c12 = h01 * h02 - h00 * h12,
                 c22 = h00 * h11 - h01 * h01;
    // The Newton step is (adj(H) t) / det; it is kept times det so that
    // no division waits on det: the Cayley quaternion below is normalised
    // anyway, so (det, adj(H) t / 2) turns as (1, step / 2) does.
    ox = c00 * t0 + c01 * t1 + c02 * t2;
    oy = c01 * t0 + c11 * t1 + c12 * t2;
    oz = c02 * t0 + c12 * t1 + c22 * t2;
    scale = det;
  } else {  // far or singular: gradient step
    const double inv = 1.0 / (std::abs(trace) + 1e-9 * m.norm() + 1e-300);
    ox = t0 * inv;
    oy = t1 * inv;
    oz = t2 * inv;
    scale = 1.0;
  }
  const double o_sq = ox * ox + oy * oy + oz * oz, scale_sq = scale * scale;
  // negligible (or NaN): keep the rotation
  if (!(o_sq > 1e-24 * scale_sq)) return;
  // The step as a rotation through the Cayley map, quaternion (1, o / 2)
  // normalised: the same axis, angle 2 atan(|o| / 2), which agrees with
  // exp(o) to third order, so Newton's convergence is kept; it needs no
  // trigonometry (a Taylor series of cos and sin lengthened the dependency
  // chain of every subbase visit by about 40 cycles). Steps beyond 1 rad are
  // shortened to it, as far from the fit the quadratic model is poor.
  if (o_sq > scale_sq)  // beyond 1 rad: the unit step, (1, step / |step| / 2) times |o|
    premultiply_rotation(std::sqrt(o_sq), 0.5 * ox, 0.5 * oy, 0.5 * oz, pose);
  else
    premultiply_rotation(scale, 0.5 * ox, 0.5 * oy, 0.5 * oz, pose);
}

}  // namespace fabrik
