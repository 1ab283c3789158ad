#include "jacobian_solver.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "joint_angles.hpp"

namespace fabrik {

namespace {
Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}
}  // namespace

JacobianSolver::JacobianSolver(const Model& model, std::vector<Target> targets,
                               SolverOptions options, JacobianOptions jacobian)
    : JacobianSolver(std::make_shared<const Model>(model), std::move(targets), options, jacobian) {}

JacobianSolver::JacobianSolver(std::shared_ptr<const Model> model_ptr, std::vector<Target> targets,
                               SolverOptions options, JacobianOptions jacobian)
    : model_holder_(std::move(model_ptr)),
      model_(*model_holder_),
      targets_(model_, std::move(targets)),
      options_(options),
      jacobian_(jacobian),
      n_seg_(static_cast<int>(model_.segments.size())) {
  const Model& model = model_;
  n_dof_ = 3 * n_seg_ + (options_.root == RootMode::free ? 3 : 0);
  const int n_t = targets_.size();
  joint_world_m_.resize(model.segments.size());
  x_world_m_.resize(static_cast<std::size_t>(n_t));
  dq_ = Eigen::VectorXd::Zero(n_dof_);
  err_ = Eigen::VectorXd::Zero(3 * n_t);
  if (jacobian_.method == JacobianMethod::damped_least_squares) {
    jac_ = Eigen::MatrixXd::Zero(3 * n_t, n_dof_);
    normal_ = Eigen::MatrixXd::Zero(n_dof_, n_dof_);
  }
  old_q_.resize(model.segments.size());
  has_limits_ = model.has_joint_limits();
  distances_m_.assign(static_cast<std::size_t>(n_t), 0.0);
  previous_m_.assign(static_cast<std::size_t>(n_t), 0.0);
}

// Jacobian transpose with the step length that minimises |e - alpha J J^T e|.
void JacobianSolver::step_transpose(std::span<const Eigen::Vector3d> target_world_m,
                                    std::span<const std::uint8_t> visible,
                                    const Posture& posture) {
  dq_.setZero();
  for (int i = 0; i < targets_.size(); ++i) {
    if (!visible[i]) continue;
    const Target& t = targets_.targets()[i];
    const Eigen::Vector3d e = t.weight * (target_world_m[i] - x_world_m_[i]);
    for (int s = model_.points[t.point].segment; s >= 0; s = model_.segments[s].parent)
      dq_.segment<3>(3 * s) += (x_world_m_[i] - joint_world_m_[s]).cross(e);
    if (options_.root == RootMode::free) dq_.segment<3>(3 * n_seg_) += e;
  }
  if (has_limits_) restrict_to_joints(posture);  // before the step length: it is for this step
  double num = 0.0, den = 0.0;  // alpha = <e, J J^T e> / <J J^T e, J J^T e>
  for (int i = 0; i < targets_.size(); ++i) {
    if (!visible[i]) continue;
    const Target& t = targets_.targets()[i];
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    for (int s = model_.points[t.point].segment; s >= 0; s = model_.segments[s].parent)
      v += dq_.segment<3>(3 * s).cross(x_world_m_[i] - joint_world_m_[s]);
    if (options_.root == RootMode::free) v += dq_.segment<3>(3 * n_seg_);
    num += t.weight * v.dot(target_world_m[i] - x_world_m_[i]);
    den += t.weight * v.squaredNorm();
  }
  dq_ *= den > 0.0 ? num / den : 0.0;
}

void JacobianSolver::step_dls(std::span<const Eigen::Vector3d> target_world_m,
                              std::span<const std::uint8_t> visible) {
  jac_.setZero();
  err_.setZero();
  for (int i = 0; i < targets_.size(); ++i) {
    if (!visible[i]) continue;  // an invisible target keeps zero rows
    const Target& t = targets_.targets()[i];
    const double w = std::sqrt(t.weight);
    err_.segment<3>(3 * i) = w * (target_world_m[i] - x_world_m_[i]);
    for (int s = model_.points[t.point].segment; s >= 0; s = model_.segments[s].parent)
      jac_.block<3, 3>(3 * i, 3 * s) = -w * skew(x_world_m_[i] - joint_world_m_[s]);
    if (options_.root == RootMode::free)
      jac_.block<3, 3>(3 * i, 3 * n_seg_) = w * Eigen::Matrix3d::Identity();
  }
  normal_.noalias() = jac_.transpose() * jac_;
  normal_.diagonal().array() += jacobian_.damping_m * jacobian_.damping_m;
  dq_.noalias() = jac_.transpose() * err_;
  Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt(normal_);  // in place: no allocation
  llt.solveInPlace(dq_);
}

// A hinge's step keeps only its part about the hinge axis (in the world, the
// parent's anatomical z); a fixed joint takes no step.
void JacobianSolver::restrict_to_joints(const Posture& posture) {
  for (int s = 1; s < n_seg_; ++s) {
    const Segment& seg = model_.segments[s];
    if (seg.joint.type == JointType::fixed) {
      dq_.segment<3>(3 * s).setZero();
    } else if (seg.joint.type == JointType::hinge) {
      const Eigen::Vector3d u = posture.segments[seg.parent].r_world *
                                (model_.segments[seg.parent].q_anatomical * Eigen::Vector3d::UnitZ());
      dq_.segment<3>(3 * s) = u * u.dot(dq_.segment<3>(3 * s));
    }
  }
}

// Applies dq: segment s turns by omega_s about its base; children follow, so a
// segment's world rotation composes every ancestor's turn (first order).
void JacobianSolver::apply(Posture& posture, const Eigen::Vector3d& root_pin_m) {
  for (int s = 0; s < n_seg_; ++s) old_q_[s] = posture.segments[s].q_world;
  for (int s = 0; s < n_seg_; ++s) {
    Eigen::Vector3d omega = dq_.segment<3>(3 * s);
    const double angle = omega.norm();
    if (angle > jacobian_.max_step_rad) omega *= jacobian_.max_step_rad / angle;
    const Eigen::Quaterniond turn =
        angle > 0.0 ? Eigen::Quaterniond(Eigen::AngleAxisd(omega.norm(), omega.normalized()))
                    : Eigen::Quaterniond::Identity();
    const int p = model_.segments[s].parent;
    Eigen::Quaterniond q = turn * old_q_[s];
    if (p >= 0) q = posture.segments[p].q_world * old_q_[p].conjugate() * q;
    posture.segments[s].set_rotation(q);
    enforce_joint_limits(model_, s, old_q_[s], posture);
  }
  SegmentPose& root = posture.segments[0];
  root.base_world_m = options_.root == RootMode::free
                          ? Eigen::Vector3d(root.base_world_m + dq_.segment<3>(3 * n_seg_))
                          : root_pin_m;
  connect_joints(model_, posture);
}

SolveResult JacobianSolver::solve(std::span<const Eigen::Vector3d> target_world_m,
                                  std::span<const std::uint8_t> visible, Posture& posture) {
  if (static_cast<int>(target_world_m.size()) != targets_.size() ||
      static_cast<int>(visible.size()) != targets_.size() ||
      static_cast<int>(posture.segments.size()) != n_seg_) {
    SolveResult mismatch;
    mismatch.status = SolveStatus::size_mismatch;
    return mismatch;
  }
  const Eigen::Vector3d root_pin_m = posture.segments[0].base_world_m;
  SolveResult result = targets_.measure(model_, posture, target_world_m, visible, distances_m_);
  StopRule stop(options_);
  for (int iteration = 0;; ++iteration) {
    if (stop.should_stop(iteration, distances_m_, previous_m_, result)) return result;
    for (int s = 0; s < n_seg_; ++s) joint_world_m_[s] = posture.segments[s].base_world_m;
    for (int i = 0; i < targets_.size(); ++i)
      x_world_m_[i] = posture.point_world_m(model_, targets_.targets()[i].point);
    if (jacobian_.method == JacobianMethod::transpose) {
      step_transpose(target_world_m, visible, posture);
    } else {
      step_dls(target_world_m, visible);
      if (has_limits_) restrict_to_joints(posture);
    }
    apply(posture, root_pin_m);
    std::copy(distances_m_.begin(), distances_m_.end(), previous_m_.begin());
    result = targets_.measure(model_, posture, target_world_m, visible, distances_m_);
    result.iterations = iteration + 1;
  }
}

}  // namespace fabrik
