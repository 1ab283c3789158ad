// Jacobian baselines on the same model, targets, options and postures as
// FabrikSolver: every segment turns about its base joint with three
// rotational degrees of freedom (world axes, linearised at the current
// posture) and a free root adds three translations. Priorities are ignored:
// these are the classic unprioritized methods the paper compares against.
// Joints with limits get the same joints as in FabrikSolver: a hinge turns
// about its axis only, a fixed joint not at all, and after every step each
// joint is brought back within its range (a projected gradient method).
//
// solve() never allocates: the Jacobian and normal matrices are sized once.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "model.hpp"
#include "posture.hpp"
#include "solve_types.hpp"
#include "target_set.hpp"

namespace fabrik {

enum class JacobianMethod {
  transpose,             // dq = alpha J^T e, alpha by Buss's optimal step for J J^T e
  damped_least_squares,  // dq = (J^T J + lambda^2 I)^-1 J^T e
};

struct JacobianOptions {
  JacobianMethod method = JacobianMethod::transpose;
  double damping_m = 0.05;    // lambda for DLS, a length as the rows are in metres
  double max_step_rad = 0.2;  // per-iteration cap on any joint's rotation
};

class JacobianSolver {
 public:
  JacobianSolver(std::shared_ptr<const Model> model, std::vector<Target> targets,
                 SolverOptions options, JacobianOptions jacobian = {});
  // The same with a copy of `model`.
  JacobianSolver(const Model& model, std::vector<Target> targets, SolverOptions options,
                 JacobianOptions jacobian = {});

  // Inputs of the wrong size give SolveStatus::size_mismatch (posture unchanged).
  SolveResult solve(std::span<const Eigen::Vector3d> target_world_m,
                    std::span<const std::uint8_t> visible, Posture& posture);

  const std::vector<Target>& targets() const { return targets_.targets(); }
  std::span<const double> target_distances_m() const { return distances_m_; }

 private:
  void step_transpose(std::span<const Eigen::Vector3d> target_world_m,
                      std::span<const std::uint8_t> visible, const Posture& posture);
  void step_dls(std::span<const Eigen::Vector3d> target_world_m,
                std::span<const std::uint8_t> visible);
  void restrict_to_joints(const Posture& posture);
  void apply(Posture& posture, const Eigen::Vector3d& root_pin_m);

  std::shared_ptr<const Model> model_holder_;
  const Model& model_;
  TargetSet targets_;
  SolverOptions options_;
  JacobianOptions jacobian_;
  int n_seg_ = 0;
  int n_dof_ = 0;
  bool has_limits_ = false;                               // 3 per segment, +3 for a free root
  std::vector<Eigen::Vector3d> joint_world_m_;  // base of each segment at the current posture
  std::vector<Eigen::Vector3d> x_world_m_;      // each target's point at the current posture
  Eigen::VectorXd dq_;      // the step: per segment omega, then root translation
  Eigen::MatrixXd jac_;     // 3 * targets x dofs
  Eigen::MatrixXd normal_;  // dofs x dofs
  Eigen::VectorXd err_;     // 3 * targets
  std::vector<Eigen::Quaterniond> old_q_;
  std::vector<double> distances_m_, previous_m_;
};

}  // namespace fabrik
