#include "solver.hpp"

#include <atomic>
#include <stdexcept>

#include "fabrik_plan.hpp"
#include "fabrik_solver.hpp"

namespace fabrik {

namespace {
std::uint64_t next_plan_id() {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

SolverPlan::SolverPlan(std::shared_ptr<const Model> model, std::vector<Target> targets,
                       SolverOptions options, std::vector<OrientationTarget> orientations)
    : options_(options), id_(next_plan_id()) {
  if (!model) throw std::invalid_argument("SolverPlan: no model");
  // Checks the targets against the model: a bad plan is refused at setup, not at its first solve.
  fabrik_ = std::make_shared<const FabrikPlan>(std::move(model), std::move(targets),
                                               std::move(orientations));
}

const Model& SolverPlan::model() const { return fabrik_->model; }
const std::shared_ptr<const Model>& SolverPlan::shared_model() const {
  return fabrik_->model_holder;
}
const std::vector<Target>& SolverPlan::targets() const { return fabrik_->targets.targets(); }
const std::vector<OrientationTarget>& SolverPlan::orientations() const {
  return fabrik_->orientations;
}

SolverWorkspace::SolverWorkspace(const SolverPlan& plan)
    : plan_id_(plan.id()), solver_(std::make_unique<FabrikSolver>(plan.fabrik_, plan.options())) {}
SolverWorkspace::~SolverWorkspace() = default;
SolverWorkspace::SolverWorkspace(SolverWorkspace&&) noexcept = default;
SolverWorkspace& SolverWorkspace::operator=(SolverWorkspace&&) noexcept = default;

std::span<const double> SolverWorkspace::target_distances_m() const {
  return solver_ ? solver_->target_distances_m() : std::span<const double>{};
}

SolveResult solve(const SolverPlan& plan, SolverWorkspace& workspace,
                  std::span<const Eigen::Vector3d> target_world_m,
                  std::span<const std::uint8_t> visible, Posture& posture) {
  return solve(plan, workspace, target_world_m, visible, {}, {}, posture);
}

SolveResult solve(const SolverPlan& plan, SolverWorkspace& workspace,
                  std::span<const Eigen::Vector3d> target_world_m,
                  std::span<const std::uint8_t> visible,
                  std::span<const Eigen::Quaterniond> q_world,
                  std::span<const std::uint8_t> orientation_visible, Posture& posture) {
  if (!workspace.solver_ || workspace.plan_id_ != plan.id()) {
    SolveResult wrong;
    wrong.status = SolveStatus::wrong_workspace;
    return wrong;
  }
  return workspace.solver_->solve(target_world_m, visible, q_world, orientation_visible, posture);
}

}  // namespace fabrik
