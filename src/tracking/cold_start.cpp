#include "cold_start.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>

namespace fabrik {

SolverOptions cold_solver_options(const SolverOptions& warm, const ColdStartSettings& cold) {
  SolverOptions o = warm;
  o.max_iterations = std::max(warm.max_iterations, cold.max_iterations);
  // From rest, FABRIK's loop without the carry can end at its fixed point far from the fit
  // (walk1's right arm, 97 mm off), where the fallback's trigger, a residual rising again,
  // never fires; the warm frames would follow it. With fallback_carry 0 it stays FABRIK's own.
  o.subtree_carry = std::max(warm.subtree_carry, warm.fallback_carry);
  // Without anchors each weaker level's pass moves the stronger levels' segments as it likes
  // and their own pass moves them back: from rest the loop can end far from the fit (one
  // synthetic start in 8, 90 mm RMS after 500 iterations) and the warm frames follow it for
  // about 0.4 s. Weak anchors are raised too: from rest there is no posture nearby to keep.
  // Anchored, the cold frame finds the posture; the warm frames keep the user's.
  o.anchor_weight = std::max(warm.anchor_weight, kColdMinAnchorWeight);
  return o;
}

void align_rigidly(const Model& model, std::span<const int> points,
                   std::span<const Eigen::Vector3d> measured_world_m,
                   std::span<const std::uint8_t> visible, Posture& posture) {
  Eigen::Vector3d model_c = Eigen::Vector3d::Zero(), measured_c = Eigen::Vector3d::Zero();
  int n = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!visible[i]) continue;
    model_c += posture.point_world_m(model, points[i]);
    measured_c += measured_world_m[i];
    ++n;
  }
  if (n == 0) return;
  model_c /= n;
  measured_c /= n;
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();  // cross-covariance, model -> measured
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!visible[i]) continue;
    h += (posture.point_world_m(model, points[i]) - model_c) *
         (measured_world_m[i] - measured_c).transpose();
  }
  Eigen::Matrix3d rot = Eigen::Matrix3d::Identity();
  // Fixed-size SVD: no allocation. Points on a line (or fewer than three) leave the turn
  // about that line undetermined: then only move.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d sv = svd.singularValues();
  if (n >= 3 && sv[1] > 1e-6 * sv[0] && sv[0] > 0.0) {
    Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
    d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
    rot = svd.matrixV() * d * svd.matrixU().transpose();
  }
  const Eigen::Quaterniond q(rot);
  for (SegmentPose& s : posture.segments) {
    s.set_rotation(q * s.q_world);
    s.base_world_m = rot * (s.base_world_m - model_c) + measured_c;
  }
}

}  // namespace fabrik
