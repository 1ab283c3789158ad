#include "paper_checks.hpp"

#include <cmath>
#include <numbers>

#include "solver/joint_angles.hpp"

namespace fabrik::bench {

using nlohmann::json;

namespace {

double off_line_m(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& u) {
  const Eigen::Vector3d v = p - a;
  return (v - v.dot(u) * u).norm();
}

// The ideal prioritized posture: the chain from the root to the strong wrist
// straight along u, towards its target.
struct Ideal {
  Eigen::Vector3d root_m, u;
  std::vector<int> chain_points;  // the strong wrist and every joint up to the root
  double strong_min_m = 0.0;      // the strong wrist's error: |target - root| - chain length
  double weak_min_m = 0.0;        // the weak wrist's best error given that straight chain
};

Ideal ideal_posture(const Experiment& e) {
  const Model& m = *e.model;
  Ideal ideal;
  const int strong_pt = e.targets[0].point, weak_pt = e.targets[1].point;
  ideal.root_m = Posture::rest(m).segments[0].base_world_m;
  const Eigen::Vector3d t_strong = e.positions_m[0], t_weak = e.positions_m[1];
  const Eigen::Vector3d& root_m = ideal.root_m;
  ideal.u = (t_strong - root_m).normalized();
  const Eigen::Vector3d& u = ideal.u;
  double chain_m = 0.0;
  for (int s = m.points[strong_pt].segment, p = strong_pt; s >= 0;
       p = m.segments[s].parent_point, s = m.segments[s].parent) {
    chain_m += (m.points[p].p_local_m).norm();
    ideal.chain_points.push_back(p);
  }
  ideal.strong_min_m = std::max(0.0, (t_strong - root_m).norm() - chain_m);

  // The weak wrist's best error given a straight strong chain: the subbase
  // segment may only twist about u, so the weak shoulder lies on a circle.
  int branch = m.points[weak_pt].segment;  // the weak side's segment off the shared chain
  double weak_arm_m = m.points[weak_pt].p_local_m.norm();
  auto on_chain = [&](int seg) { return m.is_ancestor_or_self(seg, m.points[strong_pt].segment); };
  while (!on_chain(m.segments[branch].parent)) {
    weak_arm_m += m.points[m.segments[branch].parent_point].p_local_m.norm();
    branch = m.segments[branch].parent;
  }
  const int subbase = m.segments[branch].parent;
  const Eigen::Vector3d weak_joint_local = m.points[m.segments[branch].parent_point].p_local_m;
  int strong_child = m.points[strong_pt].segment;  // the strong side's child of the subbase
  while (m.segments[strong_child].parent != subbase) strong_child = m.segments[strong_child].parent;
  const Eigen::Vector3d strong_joint_local =
      m.points[m.segments[strong_child].parent_point].p_local_m;
  double to_subbase_m = 0.0;  // from the root to the subbase's base along the chain
  for (int s = subbase; m.segments[s].parent >= 0; s = m.segments[s].parent)
    to_subbase_m += m.points[m.segments[s].parent_point].p_local_m.norm();
  const Eigen::Vector3d sub_base_m = root_m + to_subbase_m * u;
  const Eigen::Vector3d r_hat = strong_joint_local.normalized();
  const double along = weak_joint_local.dot(r_hat);
  const double radius = (weak_joint_local - along * r_hat).norm();
  const Eigen::Vector3d v = t_weak - (sub_base_m + along * u);
  const double v_par = v.dot(u), v_perp = (v - v_par * u).norm();
  ideal.weak_min_m = std::max(0.0, std::hypot(v_par, v_perp - radius) - weak_arm_m);
  return ideal;
}

}  // namespace

json check(bool pass, double value, double limit, const char* unit, const char* what) {
  return {{"pass", pass}, {"value", value}, {"limit", limit}, {"unit", unit}, {"meaning", what}};
}

json posture_checks(const Experiment& e, const Run& flat, const Run& prioritized) {
  const Model& m = *e.model;
  const Ideal ideal = ideal_posture(e);
  const double tol_m = e.solver.tolerance_m;
  const double flat_r = flat.distances_m[0], flat_l = flat.distances_m[1];
  double straight_m = 0.0;
  for (int p : ideal.chain_points)
    straight_m =
        std::max(straight_m, off_line_m(prioritized.posture.point_world_m(m, p), ideal.root_m, ideal.u));
  const double prio_strong = prioritized.distances_m[0], prio_weak = prioritized.distances_m[1];
  json checks = json::object();
  checks["flat_balanced"] =
      check(std::abs(flat_r - flat_l) <= tol_m, std::abs(flat_r - flat_l) * 1e3, tol_m * 1e3, "mm",
            "without priorities the two wrist errors are equal (posture centred)");
  checks["prioritized_chain_straight"] = check(
      straight_m <= tol_m, straight_m * 1e3, tol_m * 1e3, "mm",
      "with priorities every joint from the root to the strong wrist lies on the line root-target");
  checks["prioritized_strong_at_minimum"] =
      check(std::abs(prio_strong - ideal.strong_min_m) <= tol_m,
            (prio_strong - ideal.strong_min_m) * 1e3, tol_m * 1e3, "mm",
            "strong wrist error minus the geometric minimum |target - root| - chain length");
  checks["prioritized_weak_at_constrained_minimum"] =
      check(prio_weak - ideal.weak_min_m <= tol_m, (prio_weak - ideal.weak_min_m) * 1e3,
            tol_m * 1e3, "mm", "weak wrist error minus the best possible while the strong chain is straight");
  checks["priorities_favour_strong"] =
      check(prio_strong < flat_r, (flat_r - prio_strong) * 1e3, 0.0, "mm",
            "the strong wrist gets closer with priorities than without");
  return {{"geometric_minimum_mm",
           {{"strong", ideal.strong_min_m * 1e3}, {"weak_given_strong", ideal.weak_min_m * 1e3}}},
          {"checks", checks},
          {"root_m", {ideal.root_m.x(), ideal.root_m.y(), ideal.root_m.z()}}};
}

double max_limit_excess_deg(const Model& model, const Posture& posture) {
  double worst_rad = 0.0;
  for (int s = 1; s < static_cast<int>(model.segments.size()); ++s) {
    const JointLimits& j = model.segments[s].joint;
    if (!j.limited()) continue;
    const Eigen::Vector3d a = joint_angles_rad(model, posture, s);
    for (int k = 0; k < 3; ++k) {
      // On the circle (a_z, a_y): the angle from lo, counter-clockwise, within the range's width.
      const double from_lo = std::remainder(a[k] - j.min_rad[k], 2 * std::numbers::pi);
      const double width = j.max_rad[k] - j.min_rad[k];
      const double t = k == 1 ? a[k] - j.min_rad[k] : (from_lo < 0 && width >= 2 * std::numbers::pi - 1e-12 ? 0.0 : from_lo);
      if (t >= 0.0 && t <= width) continue;
      const double to_hi = std::remainder(a[k] - j.max_rad[k], 2 * std::numbers::pi);
      worst_rad = std::max(worst_rad, std::min(std::abs(std::remainder(a[k] - j.min_rad[k], 2 * std::numbers::pi)), std::abs(to_hi)));
    }
  }
  return worst_rad * 180.0 / std::numbers::pi;
}

}  // namespace fabrik::bench
