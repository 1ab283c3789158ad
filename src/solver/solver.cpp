#include "solver.hpp"

#include <atomic>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "common/format_number.hpp"
#include "fabrik_plan.hpp"
#include "fabrik_solver.hpp"

namespace fabrik {

namespace {
std::uint64_t next_plan_id() {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(1, std::memory_order_relaxed);
}

bool finite(const Eigen::Vector3d& p) {
  return p.allFinite();
}
bool usable(const Eigen::Quaterniond& q) {
  return q.coeffs().allFinite() && q.squaredNorm() > 0.0;
}

// A visible target, a visible orientation or the start posture that is not finite would
// spread NaN into every segment it reaches, and into every warm start after: refused. Only
// called with spans of the plan's sizes.
bool finite_inputs(std::span<const Eigen::Vector3d> target_world_m,
                   std::span<const std::uint8_t> visible,
                   std::span<const Eigen::Quaterniond> q_world,
                   std::span<const std::uint8_t> orientation_visible, const Posture& posture) {
  for (std::size_t i = 0; i < target_world_m.size(); ++i)
    if (visible[i] && !finite(target_world_m[i])) return false;
  for (std::size_t k = 0; k < q_world.size(); ++k)
    if (orientation_visible[k] && !usable(q_world[k])) return false;
  for (const SegmentPose& s : posture.segments)
    if (!usable(s.q_world) || !finite(s.base_world_m)) return false;
  return true;
}
}  // namespace

std::string solver_options_problem(const SolverOptions& o) {
  const std::pair<const char*, double> amounts[] = {
      {"tolerance_m", o.tolerance_m},       {"stall_tolerance_m", o.stall_tolerance_m},
      {"anchor_weight", o.anchor_weight},   {"subtree_carry", o.subtree_carry},
      {"fallback_carry", o.fallback_carry}, {"orientation_lever_m", o.orientation_lever_m}};
  for (const auto& [name, value] : amounts)
    if (!std::isfinite(value) || value < 0.0)  // %g: -1e-07, not to_string's -0.000000
      return std::string(name) + " must be a finite number, not negative (is " +
             format_number("%g", value) + ")";
  if (o.orientation_lever_m == 0.0) return "orientation_lever_m must be positive (is 0)";
  if (o.max_iterations < 1)
    return "max_iterations must be at least 1 (is " + std::to_string(o.max_iterations) + ")";
  if (o.level_passes < 1)
    return "level_passes must be at least 1 (is " + std::to_string(o.level_passes) + ")";
  return {};
}

SolverPlan::SolverPlan(std::shared_ptr<const Model> model, std::vector<Target> targets,
                       SolverOptions options, std::vector<OrientationTarget> orientations)
    : options_(options), id_(next_plan_id()) {
  if (!model) throw std::invalid_argument("SolverPlan: no model");
  if (const std::string why = solver_options_problem(options_); !why.empty())
    throw std::invalid_argument("SolverPlan: " + why);
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
  const std::size_t targets = plan.targets().size(), orientations = plan.orientations().size();
  if (target_world_m.size() == targets && visible.size() == targets &&
      q_world.size() == orientations && orientation_visible.size() == orientations &&
      posture.segments.size() == plan.model().segments.size() &&
      !finite_inputs(target_world_m, visible, q_world, orientation_visible, posture)) {
    SolveResult refused;
    refused.status = SolveStatus::non_finite_input;
    return refused;
  }
  return workspace.solver_->solve(target_world_m, visible, q_world, orientation_visible, posture);
}

}  // namespace fabrik
