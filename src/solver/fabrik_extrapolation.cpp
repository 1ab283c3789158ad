// FabrikSolver's extrapolation of the convergence loop (SolverOptions::extrapolate).
//
// With joint limits and the subtree carry, an iteration is a sweep of block coordinate
// descent over the joints, and it converges linearly: where two joints share a valley (a
// thigh's axial rotation and the knee hinge it aims), every iteration covers about the same
// fraction of what is left, 8 % on subject01_walk1, so the steps shrink geometrically along a
// nearly fixed direction. Two such steps tell where they lead: after iterations with steps d1
// then d2 = rho d1 (aligned), the rest is about d2 rho / (1 - rho) further along d2 (Aitken's
// delta-squared extrapolation, applied to the joint coordinates). The solver takes that jump
// when the steps are aligned, projects it onto the joint ranges, and keeps it only when it
// lowers the weighted squared distance of the targets; the loop then goes on from there.
#include <algorithm>
#include <cmath>

#include "fabrik_solver.hpp"

namespace fabrik {

namespace {

// The difference b - a of two turns, as a turn.
Turn turn_difference(const Turn& b, const Turn& a) {
  return {b.c * a.c + b.s * a.s, b.s * a.c - b.c * a.s};
}

// t moved on by `factor` times the small turn d: the angle atan(factor tan(d)) ~ factor d.
// Exact enough for a jump that is verified before it is kept.
Turn turn_ahead(const Turn& t, const Turn& d, double factor) {
  const double x = d.c > 0.0 ? factor * d.s / d.c : 0.0;
  const double inv = 1.0 / std::sqrt(1.0 + x * x);
  const Turn step{inv, x * inv};
  return {t.c * step.c - t.s * step.s, t.s * step.c + t.c * step.s};
}

// q turned on by the small rotation of `v` (a rotation vector) times `factor`.
Eigen::Quaterniond rotation_ahead(const Eigen::Quaterniond& q, const Eigen::Vector3d& v,
                                  double factor) {
  const Eigen::Vector3d h = 0.5 * factor * v;
  return (q * Eigen::Quaterniond(1.0, h.x(), h.y(), h.z())).normalized();
}

// The small rotation vector of the unit quaternion d (2 vec(d), on the short side).
Eigen::Vector3d rotation_vector(const Eigen::Quaterniond& d) {
  return d.w() < 0.0 ? Eigen::Vector3d(-2.0 * d.vec()) : Eigen::Vector3d(2.0 * d.vec());
}

}  // namespace

// The rotation of segment s relative to its parent (the root: its world rotation).
Eigen::Quaterniond FabrikSolver::relative_rotation(int s, const Posture& posture) const {
  const int parent = model_.segments[s].parent;
  return parent < 0 ? posture.segments[s].q_world
                    : posture.segments[parent].q_world.conjugate() * posture.segments[s].q_world;
}

// The sum of weight * distance^2 over the visible targets (the solve extrapolates with one
// level only), from distances_m_ as measure() left them.
double FabrikSolver::weighted_error_m2() const {
  double sum = 0.0;
  const int n_point = targets_.size();
  for (int i = 0; i < n_point; ++i)
    if (marked_visible_[i]) sum += targets_.targets()[i].weight * distances_m_[i] * distances_m_[i];
  for (std::size_t k = 0; k < orientations_.size(); ++k)
    if (orient_visible_[k]) {
      const double d = distances_m_[n_point + k];
      sum += orientations_[k].weight * d * d;
    }
  return sum;
}

// Records the state after an iteration and the step that led to it. Returns the size of the
// step (metres: a turn counts as its angle times the orientation lever) and its dot product
// with the step before.
void FabrikSolver::record_step(const Posture& posture, double& step_sq, double& dot) {
  const double lever = options_.orientation_lever_m;
  step_sq = 0.0;
  dot = 0.0;
  auto add = [&](Eigen::Vector3d& previous, const Eigen::Vector3d& now) {
    step_sq += now.squaredNorm();
    dot += now.dot(previous);
    previous = now;
  };
  const Eigen::Vector3d base_step = posture.segments[0].base_world_m - step_base_m_;
  step_base_m_ = posture.segments[0].base_world_m;
  add(last_base_step_m_, base_step);
  for (int s = 0; s < n_seg_; ++s) {
    Eigen::Vector3d v;
    if (limited_[s]) {
      // Per angle the sine of its change (its change, for the small steps this is about).
      const Turns& now = turns_[s];
      for (int k = 0; k < 3; ++k) {
        step_turn_[s][k] = turn_difference(now[k], step_turns_[s][k]);
        v[k] = lever * step_turn_[s][k].s;
      }
      step_turns_[s] = now;
    } else {
      const Eigen::Quaterniond rel = relative_rotation(s, posture);
      v = lever * rotation_vector(step_rel_q_[s].conjugate() * rel);
      step_rel_q_[s] = rel;
    }
    add(last_step_m_[s], v);
  }
}

void FabrikSolver::start_steps(const Posture& posture) {
  step_base_m_ = posture.segments[0].base_world_m;
  last_base_step_m_.setZero();
  for (int s = 0; s < n_seg_; ++s) {
    step_turns_[s] = turns_[s];
    step_rel_q_[s] = relative_rotation(s, posture);
    last_step_m_[s].setZero();
  }
  steps_recorded_ = 0;
}

// After an iteration: when its step and the one before point the same way and shrink slowly
// (by kMinRate or more of the step before: a faster loop gains less from a jump than the jump
// costs to try), jump ahead by rho / (1 - rho) of the last step (at most kMaxJump), within the
// joint ranges, and keep the jump if it lowers the weighted error. Returns true if it was kept (the
// posture, the joint angles and distances_m_ then describe the jumped posture).
bool FabrikSolver::extrapolate(std::span<const Eigen::Vector3d> target_world_m,
                               std::span<const std::uint8_t> visible, Posture& posture,
                               SolveResult& result) {
  double step_sq = 0.0, dot = 0.0;
  const double previous_sq = previous_step_sq_;
  record_step(posture, step_sq, dot);
  previous_step_sq_ = step_sq;
  if (++steps_recorded_ < 2 || !(previous_sq > 0.0) || !(step_sq > 0.0)) return false;
  // Aligned (cosine above kMinAlignment) and shrinking.
  const double rho = std::sqrt(step_sq / previous_sq);
  if (rho < kMinRate || rho >= 1.0) return false;
  if (dot < kMinAlignment * std::sqrt(step_sq * previous_sq)) return false;
  const double factor = std::min(kMaxJump, rho / (1.0 - rho));
  const double before_m2 = weighted_error_m2();

  // The jumped posture, root first (segments come parent first).
  Posture& jump = jump_;
  const double lever = options_.orientation_lever_m;
  for (int s = 0; s < n_seg_; ++s) {
    const Segment& seg = model_.segments[s];
    SegmentPose& pose = jump.segments[s];
    Turns& turns = jump_turns_[s];
    if (s == 0) {
      pose.base_world_m =
          options_.root == RootMode::free
              ? Eigen::Vector3d(posture.segments[0].base_world_m + factor * last_base_step_m_)
              : posture.segments[0].base_world_m;
    } else {
      pose.base_world_m = jump.point_world_m(model_, seg.parent_point);
    }
    const Eigen::Quaterniond& q_parent =
        s == 0 ? Eigen::Quaterniond::Identity() : jump.segments[seg.parent].q_world;
    if (!limited_[s]) {
      pose.set_unit_rotation(q_parent *
                             rotation_ahead(step_rel_q_[s], last_step_m_[s] / lever, factor));
      continue;
    }
    if (seg.joint.type == JointType::fixed) {
      jump_rel_q_[s] = Eigen::Quaterniond::Identity();
      pose.set_unit_rotation(q_parent);
      continue;
    }
    const JointArcs& arcs = arcs_[s];
    for (int k = 0; k < 3; ++k)
      turns[k] = arcs.clamp(k, turn_ahead(turns_[s][k], step_turn_[s][k], factor), turns_[s][k]);
    jump_rel_q_[s] = hinge_[s] ? quaternion_about(turns[0], hinge_axis_local_[s])
                               : joint_rotation(s, turns).normalized();
    pose.set_unit_rotation(q_parent * jump_rel_q_[s]);
  }
  std::copy(distances_m_.begin(), distances_m_.end(), jump_distances_m_.begin());
  const SolveResult jumped = measure(target_world_m, visible, jump);
  if (!(weighted_error_m2() < before_m2)) {
    std::copy(jump_distances_m_.begin(), jump_distances_m_.end(), distances_m_.begin());
    return false;
  }
  std::copy(jump.segments.begin(), jump.segments.end(), posture.segments.begin());
  for (int s = 1; s < n_seg_; ++s) {
    if (!limited_[s]) continue;
    turns_[s] = jump_turns_[s];
    rel_q_[s] = jump_rel_q_[s];
  }
  const int iterations = result.iterations, passes = result.passes, jumps = result.jumps;
  result = jumped;
  result.iterations = iterations;
  result.passes = passes;
  result.jumps = jumps + 1;
  start_steps(posture);  // the next jump needs two fresh steps
  previous_step_sq_ = 0.0;
  return true;
}

}  // namespace fabrik
