/// @file
/// The solver as a library user holds it (Pinocchio's Model/Data split): a SolverPlan is the
/// problem, fixed once (model, targets, options) and shared read-only between threads; a
/// SolverWorkspace is one thread's scratch for solving that plan. solve() takes both and
/// checks that they belong together and that the inputs have the plan's sizes and are finite:
/// a mismatch is a status value (SolveStatus::wrong_workspace, SolveStatus::size_mismatch,
/// SolveStatus::non_finite_input), never an exception and never undefined behaviour. A solve
/// allocates nothing.
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

namespace fabrik {

class FabrikSolver;
struct FabrikPlan;

/// The problem: which model points are pulled (targets), which segments are turned
/// (orientation targets), and how the loop runs (options). Immutable once made.
class SolverPlan {
 public:
  /// Throws std::invalid_argument when a target names a point or segment the model lacks, or
  /// has a weight that is not positive and finite, or when the options cannot run a solve
  /// (solver_options_problem: NaN, a negative length, max_iterations below 1).
  SolverPlan(std::shared_ptr<const Model> model, std::vector<Target> targets,
             SolverOptions options = {}, std::vector<OrientationTarget> orientations = {});

  const Model& model() const;  ///< the model the targets index into
  /// The same model, shared (for holders that must keep it alive).
  const std::shared_ptr<const Model>& shared_model() const;
  /// The point targets, in the order solve() takes their positions.
  const std::vector<Target>& targets() const;
  /// The orientation targets, in the order solve() takes their rotations.
  const std::vector<OrientationTarget>& orientations() const;
  const SolverOptions& options() const { return options_; }  ///< how the loop runs
  /// Unique among the plans made in this process (copies share it: they are the same problem).
  std::uint64_t id() const { return id_; }

 private:
  friend class SolverWorkspace;
  // The tables derived from model and targets, made once and shared read-only by every copy
  // of the plan and every workspace made for it.
  std::shared_ptr<const FabrikPlan> fabrik_;
  SolverOptions options_;
  std::uint64_t id_;
};

/// One thread's scratch space for one plan, sized when made; it shares the plan's tables
/// (read-only) instead of copying them. Movable, not copyable.
class SolverWorkspace {
 public:
  /// Allocates everything a solve of `plan` needs (at setup, not on the frame path).
  explicit SolverWorkspace(const SolverPlan& plan);
  ~SolverWorkspace();
  /// Takes the scratch space; solving with the moved-from workspace gives wrong_workspace.
  SolverWorkspace(SolverWorkspace&&) noexcept;
  /// Takes the scratch space; solving with the moved-from workspace gives wrong_workspace.
  SolverWorkspace& operator=(SolverWorkspace&&) noexcept;
  SolverWorkspace(const SolverWorkspace&) = delete;
  SolverWorkspace& operator=(const SolverWorkspace&) = delete;

  /// The plan this workspace was made for (SolverPlan::id).
  std::uint64_t plan_id() const { return plan_id_; }
  /// Distance of each target to its point after the last solve (NaN where not visible):
  /// point targets, then orientation targets (their angle times options().orientation_lever_m).
  std::span<const double> target_distances_m() const;

 private:
  friend SolveResult solve(const SolverPlan&, SolverWorkspace&, std::span<const Eigen::Vector3d>,
                           std::span<const std::uint8_t>, std::span<const Eigen::Quaterniond>,
                           std::span<const std::uint8_t>, Posture&);
  std::uint64_t plan_id_;
  std::unique_ptr<FabrikSolver> solver_;
};

/// Moves `posture` (the start: the previous frame's result, or Posture::rest) so that each
/// visible target's point meets target_world_m[i] (metres, world frame), strongest priority
/// level first. target_world_m and visible have one entry per plan.targets(). The posture is
/// left unchanged when the status is size_mismatch, wrong_workspace, non_finite_input (a
/// visible target, or the start posture, holds NaN or an infinity) or no_targets.
SolveResult solve(const SolverPlan& plan, SolverWorkspace& workspace,
                  std::span<const Eigen::Vector3d> target_world_m,
                  std::span<const std::uint8_t> visible, Posture& posture);

/// The same with orientation targets: q_world[k] (the segment's desired world rotation, unit)
/// and orientation_visible[k] belong to plan.orientations()[k].
SolveResult solve(const SolverPlan& plan, SolverWorkspace& workspace,
                  std::span<const Eigen::Vector3d> target_world_m,
                  std::span<const std::uint8_t> visible,
                  std::span<const Eigen::Quaterniond> q_world,
                  std::span<const std::uint8_t> orientation_visible, Posture& posture);

}  // namespace fabrik
