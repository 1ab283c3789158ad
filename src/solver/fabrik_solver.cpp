#include "fabrik_solver.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "joint_angles.hpp"
#include "joint_fit.hpp"
#include "rotation_fit.hpp"

namespace fabrik {

namespace {
// Coordinate-ascent sweeps of a limited segment's joint angles per visit: the
// convergence loop revisits the segment, as with the one Newton step.
constexpr int kJointSweeps = 1;

// len / sqrt(dist_sq), as len * sqrt(dist_sq) * (1 / dist_sq): the square
// root and the division do not wait for each other, which shortens every
// FABRIK step's chain of dependent operations (within 2 ulp of the quotient).
inline double length_over(double len, double dist_sq) {
  return len * std::sqrt(dist_sq) * (1.0 / dist_sq);
}
}  // namespace

namespace {
// Moments of points a (in a child's frame) moved into its parent's frame, a_parent = o + R a.
FabrikSolver::Moments moved(const FabrikSolver::Moments& m, const Eigen::Matrix3d& r,
                            const Eigen::Vector3d& o) {
  FabrikSolver::Moments out;
  out.da.noalias() = m.d * o.transpose();
  out.da.noalias() += m.da * r.transpose();
  out.a.noalias() = m.w * o + r * m.a;
  out.d = m.d;
  out.w = m.w;
  out.count = m.count;
  return out;
}
void add(FabrikSolver::Moments& to, const FabrikSolver::Moments& m) {
  to.da += m.da;
  to.d += m.d;
  to.a += m.a;
  to.w += m.w;
  to.count += m.count;
}
void add_scaled(FabrikSolver::Moments& to, const FabrikSolver::Moments& m, double f) {
  to.da += f * m.da;
  to.d += f * m.d;
  to.a += f * m.a;
  to.w += f * m.w;
  to.count += m.count;
}
// One point a (segment frame) pulled towards d (from the moments' origin) with weight w.
void add_point(FabrikSolver::Moments& m, const Eigen::Vector3d& d, const Eigen::Vector3d& a,
               double w) {
  m.da.noalias() += (w * d) * a.transpose();
  m.d += w * d;
  m.a += w * a;
  m.w += w;
  ++m.count;
}
}  // namespace

FabrikSolver::FabrikSolver(const Model& model, std::vector<Target> targets, SolverOptions options,
                           std::vector<OrientationTarget> orientations)
    : FabrikSolver(std::make_shared<const Model>(model), std::move(targets), options,
                   std::move(orientations)) {}

FabrikSolver::FabrikSolver(std::shared_ptr<const Model> model, std::vector<Target> targets,
                           SolverOptions options, std::vector<OrientationTarget> orientations)
    : FabrikSolver(std::make_shared<const FabrikPlan>(std::move(model), std::move(targets),
                                                      std::move(orientations)),
                   options) {}

namespace {
const FabrikPlan& checked(const std::shared_ptr<const FabrikPlan>& plan) {
  if (!plan) throw std::invalid_argument("FabrikSolver: no plan");
  return *plan;
}
}  // namespace

FabrikSolver::FabrikSolver(std::shared_ptr<const FabrikPlan> plan, SolverOptions options)
    : plan_(std::move(plan)),
      model_(checked(plan_).model),
      targets_(plan_->targets),
      n_seg_(plan_->n_seg),
      n_pass_(plan_->n_pass),
      any_limited_(plan_->any_limited),
      slots_(plan_->slots),
      slot_first_(plan_->slot_first),
      target_segment_(plan_->target_segment),
      limited_(plan_->limited),
      parent_of_limited_(plan_->parent_of_limited),
      joint_parent_(plan_->joint_parent),
      joint_child_(plan_->joint_child),
      arcs_(plan_->arcs),
      hinge_(plan_->hinge),
      hinge_axis_local_(plan_->hinge_axis_local),
      orientations_(plan_->orientations),
      orient_level_(plan_->orient_level),
      orient_first_(plan_->orient_first),
      orient_by_segment_(plan_->orient_by_segment),
      has_orientation_(plan_->has_orientation),
      options_(options) {
  const std::size_t n_seg = static_cast<std::size_t>(n_seg_);
  const std::size_t n_targets = targets_.targets().size();
  active_.assign(static_cast<std::size_t>(n_pass_) * n_seg, 0);
  drivers_.resize(static_cast<std::size_t>(plan_->max_drivers));
  subtree_.resize(n_seg);
  own_.resize(static_cast<std::size_t>(n_pass_) * n_seg);
  local_.resize(n_seg);
  children_.resize(n_seg);
  slot_weight_.assign(static_cast<std::size_t>(n_pass_) * slots_.size(), 0.0);
  pass_has_riders_.assign(static_cast<std::size_t>(n_pass_), 0);
  driven_.assign(static_cast<std::size_t>(n_seg_), 0);
  marked_visible_.assign(n_targets, 0);
  weight_scale_.assign(n_targets, 1.0);
  link_.assign(n_seg, 0);
  link_tip_m_.assign(n_seg, Eigen::Vector3d::Zero());
  start_.resize(n_seg);
  jump_.segments.resize(n_seg);
  jump_turns_.resize(n_seg);
  step_turns_.resize(n_seg);
  step_turn_.resize(n_seg);
  jump_rel_q_.assign(n_seg, Eigen::Quaterniond::Identity());
  step_rel_q_.assign(n_seg, Eigen::Quaterniond::Identity());
  last_step_m_.assign(n_seg, Eigen::Vector3d::Zero());
  const std::size_t n_all = n_targets + orientations_.size();
  distances_m_.assign(n_all, 0.0);
  previous_m_.assign(n_all, 0.0);
  jump_distances_m_.assign(n_all, 0.0);
  level_previous_m_.assign(n_all, 0.0);
  orient_weight_.assign(static_cast<std::size_t>(n_pass_) * orientations_.size(), 0.0);
  orient_r_.assign(orientations_.size(), Eigen::Matrix3d::Identity());
  orient_q_.assign(orientations_.size(), Eigen::Quaterniond::Identity());
  orient_visible_.assign(orientations_.size(), 0);
  marked_orient_visible_.assign(orientations_.size(), 0);
  turns_.resize(n_seg);
  rel_q_.assign(n_seg, Eigen::Quaterniond::Identity());
}

void FabrikSolver::mark_active(std::span<const std::uint8_t> visible) {
  if (marked_ && std::equal(visible.begin(), visible.end(), marked_visible_.begin()) &&
      std::equal(orient_visible_.begin(), orient_visible_.end(), marked_orient_visible_.begin()))
    return;
  std::copy(visible.begin(), visible.end(), marked_visible_.begin());
  std::copy(orient_visible_.begin(), orient_visible_.end(), marked_orient_visible_.begin());
  marked_ = true;
  std::fill(active_.begin(), active_.end(), std::uint8_t{0});
  const bool anchors = options_.use_priorities && options_.anchor_weight > 0.0;
  // A visible target marks the path from its segment to the root, for its
  // own level's pass and, as an anchor, for the weaker levels' passes.
  auto mark = [&](int segment, int level_index) {
    const int own = options_.use_priorities ? level_index : 0;
    for (int pass = anchors ? 0 : own; pass <= own; ++pass) {
      const std::uint8_t bit = pass == own ? kOwn : kAnchor;
      for (int s = segment; s >= 0; s = model_.segments[s].parent) {
        std::uint8_t& flag = active_[pass * n_seg_ + s];
        if (flag & bit) break;  // the rest of the path is already marked
        flag |= bit;
      }
    }
  };
  for (int i = 0; i < targets_.size(); ++i)
    if (visible[i]) mark(model_.points[targets_.targets()[i].point].segment, targets_.level_index(i));
  const int n_orient = static_cast<int>(orientations_.size());
  for (int k = 0; k < n_orient; ++k)
    if (orient_visible_[k]) mark(orientations_[k].segment, orient_level_[k]);
  for (int pass = 0; pass < n_pass_; ++pass)
    for (int k = 0; k < n_orient; ++k) {
      double w = 0.0;
      if (orient_visible_[k]) {
        const int level = orient_level_[k];
        w = orientations_[k].weight;
        if (options_.use_priorities)
          w = level == pass ? w : level > pass ? w * options_.anchor_weight : 0.0;
      }
      orient_weight_[static_cast<std::size_t>(pass * n_orient + k)] =
          w * options_.orientation_lever_m * options_.orientation_lever_m;
    }
  const int n_slots = static_cast<int>(slots_.size());
  for (int pass = 0; pass < n_pass_; ++pass) {
    double* weight = slot_weight_.data() + static_cast<std::ptrdiff_t>(pass) * n_slots;
    for (int k = 0; k < n_slots; ++k) {
      const int source = slots_[k].source;
      if (source >= 0) {
        weight[k] = visible[source] ? pass_weight(pass, source) : 0.0;
      } else {
        const std::uint8_t act = activity(pass, ~source);
        weight[k] = !act ? 0.0 : act & kAnchor ? options_.anchor_weight : 1.0;
      }
    }
    std::uint8_t riders = 0;
    for (int s = 1; s < n_seg_; ++s) riders |= !active(pass, s);
    pass_has_riders_[pass] = riders;
  }
  for (int s = 0; s < n_seg_; ++s) {
    std::uint8_t driven = 0;
    for (int pass = 0; pass < pass_count(); ++pass) driven |= pass_runs(pass) && active(pass, s);
    driven_[s] = driven;
  }
  // A segment with a single slot that is active in every pass that runs is a
  // link: nothing but that slot's point ever pulls on it and nothing reads
  // its other points during the solve (no rider hangs off it, its only
  // target is that point), so the passes move that point alone, the classic
  // FABRIK way, and its rotation follows once at the end: the minimal turn
  // from the start, the same joint positions for a fraction of the work.
  // A free root is placed by its own fit, so it is never a link.
  const int passes = pass_count();
  bool runs = false;
  for (int pass = 0; pass < passes; ++pass) runs = runs || pass_runs(pass);
  any_link_ = false;
  for (int s = 0; s < n_seg_; ++s) {
    bool link = runs && slot_first_[s + 1] - slot_first_[s] == 1 &&
                (s != 0 || options_.root == RootMode::fixed) && !limited_[s] &&
                !parent_of_limited_[s] && !has_orientation_[s];
    for (int pass = 0; pass < passes && link; ++pass)
      if (pass_runs(pass) && !active(pass, s)) link = false;
    link_[s] = link;
    any_link_ = any_link_ || link;
  }
}

void FabrikSolver::set_weight_scale(std::span<const double> scale) {
  if (scale.size() != weight_scale_.size() ||
      std::equal(scale.begin(), scale.end(), weight_scale_.begin()))
    return;
  std::copy(scale.begin(), scale.end(), weight_scale_.begin());
  marked_ = false;  // the slots' weights follow
}

double FabrikSolver::pass_weight(int pass, int t) const {
  const double w = targets_.targets()[t].weight * weight_scale_[t];
  if (!options_.use_priorities) return w;
  const int level = targets_.level_index(t);
  if (level == pass) return w;
  return level > pass ? w * options_.anchor_weight : 0.0;
}

// Collects the points of segment s that this pass pulls on: its own visible
// targets, and the joint of every active child, pulled to that child's base.
[[gnu::always_inline]] inline int FabrikSolver::gather(
    int pass, int s, std::span<const Eigen::Vector3d> target_world_m,
    std::span<const std::uint8_t> /*visible*/, const Posture& posture) {
  int n = 0;
  const double* weight =
      slot_weight_.data() + static_cast<std::ptrdiff_t>(pass) * static_cast<int>(slots_.size());
  for (int k = slot_first_[s], end = slot_first_[s + 1]; k < end; ++k) {
    if (weight[k] <= 0.0) continue;
    const Slot& slot = slots_[k];
    drivers_[n++] = {&slot, &desired_m(slot, target_world_m, posture), weight[k]};
  }
  gather_orientations(pass, s);
  return n;
}

// Sums the orientation targets of segment s that take part in this pass (see gather).
void FabrikSolver::gather_orientations(int pass, int s) {
  orient_on_ = false;
  if (has_orientation_[s]) {
    // Three virtual points at the lever along the segment's axes, pulled to
    // where the desired rotation puts them about the base: their alignment
    // term sum_i (R_d a_i)(R a_i)^T is lever^2 R_d R^T, and they pull no
    // translation. orient_m_ holds sum w lever^2 R_d over this pass's targets.
    const int n_orient = static_cast<int>(orientations_.size());
    const double* w = orient_weight_.data() + static_cast<std::ptrdiff_t>(pass) * n_orient;
    orient_m_.setZero();
    for (int i = orient_first_[s]; i < orient_first_[s + 1]; ++i) {
      const int k = orient_by_segment_[i];
      if (w[k] <= 0.0) continue;
      orient_m_.noalias() += w[k] * orient_r_[k];
      orient_on_ = true;
    }
  }
}

// Forward reaching for one segment: each driver proposes a base position (the
// classic FABRIK step along the line from its desired position to the current
// base); the base moves to their weighted mean, then the segment turns about it.
// With `turn` false only the base moves: for a non-root segment that only one
// point can ever drive (one target or one child, no other), the turn is
// deferred to the backward pass, which turns it about its final base anyway.
// Joint positions are exactly those of turning twice (the parent's forward
// step reads only this segment's base; the backward turn aims the driver at
// the same place); only the twist about the driver's axis, which no target
// constrains, differs: it is then one minimal turn from the start. A segment
// with several possible drivers (a subbase) always turns, since in a pass
// where only one of them pulls, its twist still carries the others' joints.
void FabrikSolver::place_with_candidates(int n, SegmentPose& pose, bool turn) const {
  const double bx = pose.base_world_m.x(), by = pose.base_world_m.y(), bz = pose.base_world_m.z();
  double sx = 0.0, sy = 0.0, sz = 0.0, weight_sum = 0.0;
  for (int k = 0; k < n; ++k) {
    const Driver& d = drivers_[k];
    const double dx = d.d_world().x(), dy = d.d_world().y(), dz = d.d_world().z();
    const double ux = bx - dx, uy = by - dy, uz = bz - dz;
    const double dist_sq = ux * ux + uy * uy + uz * uz;
    if (dist_sq > 1e-24) {
      const double f = length_over(d.weight * d.a_norm_m(), dist_sq);
      sx += d.weight * dx + f * ux;
      sy += d.weight * dy + f * uy;
      sz += d.weight * dz + f * uz;
    } else {
      const Eigen::Vector3d candidate = d.d_world() - pose.r_world * d.a_local();
      sx += d.weight * candidate.x();
      sy += d.weight * candidate.y();
      sz += d.weight * candidate.z();
    }
    weight_sum += d.weight;
  }
  // Only orientation targets pull (n == 0): the base stays.
  const double inv = n > 0 ? 1.0 / weight_sum : 0.0;
  const Eigen::Vector3d base_m =
      n > 0 ? Eigen::Vector3d(sx * inv, sy * inv, sz * inv) : pose.base_world_m;
  if (turn)
    rotate_about_base(n, base_m, pose);
  else
    pose.base_world_m = base_m;
}

// Turns the segment about its (new) base so its drivers point at their desired
// positions, then puts the base there. Paper rule: the direction to the mean
// driver is aligned with the direction to the mean desired position. Rigid
// rule: least-squares rotation of all driver directions.
[[gnu::always_inline]] inline void FabrikSolver::rotate_about_base(int n,
                                                                   const Eigen::Vector3d& base_m,
                                                                   SegmentPose& pose) const {
  if (options_.segment_fit == SegmentFit::paper && (n > 1 || carry_on_) && !orient_on_) {
    Eigen::Vector3d mean_local = Eigen::Vector3d::Zero(), mean_desired = Eigen::Vector3d::Zero();
    double weight_sum = 0.0;
    if (carry_on_) {
      mean_local = carried_.a;
      mean_desired = carried_.d + carried_.w * carry_origin_m_;
      weight_sum = carried_.w;
    }
    for (int k = 0; k < n; ++k) {
      mean_local += drivers_[k].weight * drivers_[k].a_local();
      mean_desired += drivers_[k].weight * drivers_[k].d_world();
      weight_sum += drivers_[k].weight;
    }
    const Eigen::Vector3d a = pose.r_world * (mean_local / weight_sum);  // P_i(i) -> M(i)
    const Eigen::Vector3d b = mean_desired / weight_sum - base_m;        // P_i(f) -> M(f)
    turn_minimal(a, b, pose);
  } else if (n == 1 && !orient_on_ && !carry_on_) {
    // One driver: the least-squares rotation nearest the current one is the
    // minimal rotation (the rule above), which is exact and much cheaper.
    turn_minimal(pose.r_world * drivers_[0].a_local(), drivers_[0].d_world() - base_m, pose);
  } else {
    // Orientation targets (virtual points, see gather) add lever^2 w R_d R^T.
    Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
    if (orient_on_) m.noalias() = orient_m_ * pose.r_world.transpose();
    if (carry_on_) m.noalias() += carried_alignment(base_m) * pose.r_world.transpose();
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector3d a_world = pose.r_world * drivers_[k].a_local();
      m.noalias() += (drivers_[k].weight * (drivers_[k].d_world() - base_m)) * a_world.transpose();
    }
    // One Newton step per visit: the convergence loop revisits the segment, so
    // an exact inner fit buys nothing (same iterations, same residuals).
    fit_rotation_step(m, pose);
  }
  pose.base_world_m = base_m;
}

// A free root is not pulled along a chain: it is placed by a weighted rigid
// fit (Kabsch, about the centroid) of its drivers.
void FabrikSolver::free_root_fit(int n, SegmentPose& pose) const {
  if (n == 0) {  // orientation targets alone turn the root about its base
    rotate_about_base(0, pose.base_world_m, pose);
    return;
  }
  Eigen::Vector3d mean_local = Eigen::Vector3d::Zero(), mean_desired = Eigen::Vector3d::Zero();
  double weight_sum = 0.0;
  for (int k = 0; k < n; ++k) {
    mean_local += drivers_[k].weight * drivers_[k].a_local();
    mean_desired += drivers_[k].weight * drivers_[k].d_world();
    weight_sum += drivers_[k].weight;
  }
  mean_local /= weight_sum;
  mean_desired /= weight_sum;
  Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
  if (orient_on_) m.noalias() = orient_m_ * pose.r_world.transpose();
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d a_world = pose.r_world * (drivers_[k].a_local() - mean_local);
    m.noalias() +=
        (drivers_[k].weight * (drivers_[k].d_world() - mean_desired)) * a_world.transpose();
  }
  // One Newton step per visit: the convergence loop revisits the segment, so
  // an exact inner fit buys nothing (same iterations, same residuals).
  fit_rotation_step(m, pose);
  pose.base_world_m = mean_desired - pose.r_world * mean_local;
}

void FabrikSolver::forward(int pass, std::span<const Eigen::Vector3d> target_world_m,
                           std::span<const std::uint8_t> visible, Posture& posture) {
  LinkStep last;
  for (int s = n_seg_ - 1; s >= 0; --s) {
    if (!active(pass, s)) continue;
    const bool root = s == 0;
    if (root && options_.root == RootMode::fixed) continue;  // the backward pass pins it
    if (link_[s]) {
      forward_link(s, target_world_m, posture, last);
      continue;
    }
    if (limited_[s]) {
      forward_limited(pass, s, posture);
      continue;
    }
    const int n = gather(pass, s, target_world_m, visible, posture);
    if (root && options_.segment_fit == SegmentFit::rigid) {
      free_root_fit(n, posture.segments[s]);
    } else {  // see place_with_candidates for why one driver does not turn here
      place_with_candidates(n, posture.segments[s],
                            root || slot_first_[s + 1] - slot_first_[s] > 1 || orient_on_);
    }
  }
}

// A hinge turns its child about the axis u (parent frame) by theta from
// rest: a local vector a goes to R_parent (a_along + cos(theta) a_across +
// sin(theta) u x a), so the drivers' alignment with their desired vectors is
// C cos(theta) + S sin(theta) + const: its peak is exact in one step, and so
// is its clamp to the range (a sinusoid falls off on both sides of its peak).
void FabrikSolver::hinge_fit(int s, const Eigen::Matrix3d& g, Posture& posture) {
  SegmentPose& pose = posture.segments[s];
  const SegmentPose& parent = posture.segments[model_.segments[s].parent];
  // With H = R_parent^T G = sum b a^T (b: the pulls in the parent's frame), the sinusoid's
  // terms sum b . (a - u u.a) and b . (u x a) are trace(H) - u.H u and
  // u . (H21 - H12, H02 - H20, H10 - H01).
  const Eigen::Matrix3d h = parent.r_world.transpose() * g;
  const Eigen::Vector3d& u = hinge_axis_local_[s];
  const double c = h.trace() - u.dot(h * u);
  const double sn = u.dot(Eigen::Vector3d(h(2, 1) - h(1, 2), h(0, 2) - h(2, 0), h(1, 0) - h(0, 1)));
  Turn& theta = turns_[s][0];
  theta = arcs_[s].clamp(0, peak_turn(c, sn, theta), theta);
  rel_q_[s] = quaternion_about(theta, u);
  pose.set_rotation(parent.q_world * rel_q_[s]);
}

// A limited segment's forward step keeps its joint angles from its latest
// fit (so its rotation follows the parent's as the parent stands now, within
// range) and moves to meet its drivers as well as that rotation allows. Its
// base, which the parent reaches for next, then says where the segment can
// be, not where a free one would be; the backward pass fits the angles.
// (Fitting the angles here as well gives the same postures on walking data
// and synthetic motion, for half again the time.)
void FabrikSolver::forward_limited(int pass, int s, Posture& posture) const {
  SegmentPose& pose = posture.segments[s];
  pose.set_unit_rotation(posture.segments[model_.segments[s].parent].q_world * rel_q_[s]);
  // The base that best puts the drivers on their desired positions: the weighted mean of
  // d - R a, from the targets' moments and each pulling child's joint.
  const Moments& own = own_[static_cast<std::size_t>(pass * n_seg_ + s)];
  Eigen::Vector3d sum = own.d + own.w * carry_origin_m_ - pose.r_world * own.a;
  double weight_sum = own.w;
  const double* weight =
      slot_weight_.data() + static_cast<std::ptrdiff_t>(pass) * static_cast<int>(slots_.size());
  for (int k = slot_first_[s]; k < slot_first_[s + 1]; ++k) {
    const int source = slots_[k].source;
    if (weight[k] <= 0.0 || source >= 0) continue;
    sum += weight[k] * (posture.segments[~source].base_world_m - pose.r_world * slots_[k].a_local);
    weight_sum += weight[k];
  }
  if (weight_sum > 0.0) pose.base_world_m = sum / weight_sum;
}

// A link's forward step: its base moves onto the line from its one desired
// position to the base, at the link's length from it. `last`: the pass's last link step,
// which this one chains on when its desired position is the base that step just placed.
[[gnu::always_inline]] inline void FabrikSolver::forward_link(
    int s, std::span<const Eigen::Vector3d> target_world_m, Posture& posture,
    LinkStep& last) const {
  const Slot& slot = slots_[slot_first_[s]];
  const Eigen::Vector3d& d_m = desired_m(slot, target_world_m, posture);
  Eigen::Vector3d& base_m = posture.segments[s].base_world_m;
  const bool chained = slot.source < 0 && last.segment == ~slot.source;
  if (last.step(d_m, base_m, slot.a_norm_m, chained, base_m))
    last.segment = s;
  else  // on the desired position: keep the link's direction
    base_m = d_m - (link_tip_m_[s] - base_m);
}

// A link's backward step: from its new base, its point goes towards its
// desired position, at the link's length. `chained`: base_m is the tip `last` just placed.
[[gnu::always_inline]] inline void FabrikSolver::backward_link(
    int s, const Eigen::Vector3d& base_m, std::span<const Eigen::Vector3d> target_world_m,
    Posture& posture, LinkStep& last, bool chained) {
  const Slot& slot = slots_[slot_first_[s]];
  Eigen::Vector3d& tip_m = link_tip_m_[s];
  SegmentPose& pose = posture.segments[s];
  if (last.step(base_m, desired_m(slot, target_world_m, posture), slot.a_norm_m, chained, tip_m))
    last.segment = s;
  else  // on the desired position: keep the link's direction
    tip_m = base_m + (tip_m - pose.base_world_m);
  pose.base_world_m = base_m;
}

// Ends a solve: every link turns once, minimally, from its start rotation to
// point at its tip.
void FabrikSolver::turn_links(Posture& posture) const {
  for (int s = 0; s < n_seg_; ++s) {
    if (!link_[s]) continue;
    SegmentPose& pose = posture.segments[s];
    turn_minimal(pose.r_world * slots_[slot_first_[s]].a_local, link_tip_m_[s] - pose.base_world_m,
                 pose);
  }
}

// A rider (a segment nothing below pulls on in a pass) that another level's pass pulls on
// keeps the world rotation it had when this level's passes began and moves with its joint: a
// stronger level's pass leaves where a weaker one turned the limbs. Riding on the parent
// instead, the limbs turned back with a pelvis that a weak pass with weak anchors had turned,
// and the body drifted (docs/solver.md, "Riders"). A segment no pass pulls on rides rigidly
// on its parent. Nothing a pass fits reads a rider (it has no target in the pass and no
// active segment below it), so the passes leave riders out and this places them once, after
// the level's last pass, parents first.
void FabrikSolver::ride_inactive(int pass, Posture& posture) {
  for (int s = 1; s < n_seg_; ++s) {
    if (active(pass, s)) continue;
    SegmentPose& pose = posture.segments[s];
    const int parent = model_.segments[s].parent;
    if (!driven_[s]) {
      ride_on_parent(s, posture);
    } else {
      pose.set_unit_rotation(start_[s].q_world);
      // Under a parent that kept its rotation, the joint is as it was; only a rider whose
      // parent turned needs its joint checked.
      if (limited_[s] &&
          posture.segments[parent].q_world.coeffs() != start_[parent].q_world.coeffs())
        rider_within_limits(s, posture);
    }
    pose.base_world_m = joint_world_m(s, posture);
  }
}

// A limited rider that keeps its world rotation under a parent that turned, brought within
// range from its previous angles. A hinge at a bound stays on it, turning with its parent:
// the weaker level wanted it beyond, so the bound is its answer whatever the parent did; left
// a little inside, under weak anchors the hinge's next fit could leave through the other
// bound (tests/test_joints.cpp, the hinge sweep). Ball joints keep their world rotation on
// every axis: a hip at a bound turning back with the pelvis brought the drift back.
void FabrikSolver::rider_within_limits(int s, Posture& posture) {
  const Segment& seg = model_.segments[s];
  SegmentPose& pose = posture.segments[s];
  const Eigen::Quaterniond& q_parent = posture.segments[seg.parent].q_world;
  const JointArcs& arcs = arcs_[s];
  Turns& turns = turns_[s];
  if (seg.joint.type == JointType::fixed) {
    pose.set_unit_rotation(q_parent);
    return;
  }
  if (hinge_[s]) {
    if (arcs.at_bound(0, turns[0])) {
      ride_on_parent(s, posture);
      return;
    }
    const Eigen::Vector3d& u = hinge_axis_local_[s];
    turns[0] = arcs.clamp(0, twist_turn(q_parent.conjugate() * pose.q_world, u), turns[0]);
    pose.set_unit_rotation(q_parent * quaternion_about(turns[0], u));
    rel_q_[s] = q_parent.conjugate() * pose.q_world;
    return;
  }
  const Turns kept = joint_turns(s, q_parent.conjugate() * pose.q_world);
  bool moved = false;
  for (int k = 0; k < 3; ++k) {
    const Turn t = arcs.clamp(k, kept[k], turns[k]);
    moved = moved || t.c != kept[k].c || t.s != kept[k].s;
    turns[k] = t;
  }
  if (moved) pose.set_rotation(q_parent * joint_rotation(s, turns));
  rel_q_[s] = q_parent.conjugate() * pose.q_world;
}

void FabrikSolver::backward(int pass, std::span<const Eigen::Vector3d> target_world_m,
                            std::span<const std::uint8_t> visible, Posture& posture,
                            const Eigen::Vector3d& root_pin_m) {
  const bool carrying = carry_ > 0.0;
  if (any_limited_) limited_moments(pass, carrying, posture);
  LinkStep last;
  for (int s = 0; s < n_seg_; ++s) {
    SegmentPose& pose = posture.segments[s];
    const Segment& seg = model_.segments[s];
    if (s == 0) {
      if (options_.root == RootMode::free) continue;  // placed by the forward pass
      if (link_[s]) {
        backward_link(s, root_pin_m, target_world_m, posture, last, false);
        continue;
      }
      const int n = gather(pass, s, target_world_m, visible, posture);
      rotate_about_base(n, root_pin_m, pose);
      continue;
    }
    if (!active(pass, s)) continue;  // a rider: ride_inactive places it
    const Eigen::Vector3d base_m = joint_world_m(s, posture);
    if (link_[s]) {
      backward_link(s, base_m, target_world_m, posture, last, last.segment == seg.parent);
      continue;
    }
    if (limited_[s]) {
      // Its own targets and pulling children, and (with the carry) its limited subtree.
      Moments m = local_[s];
      if (carrying && parent_of_limited_[s]) add_scaled(m, children_[s], carry_);
      gather_orientations(pass, s);
      limited_fit(s, m, base_m, posture);
      continue;
    }
    const int n = gather(pass, s, target_world_m, visible, posture);
    if (carrying && parent_of_limited_[s]) carry_limited(pass, s);
    rotate_about_base(n, base_m, pose);
    carry_on_ = false;
  }
}

// SolverOptions::subtree_carry: the drivers of limited descendants (through
// limited joints only), carried rigidly at their joints' latest angles into
// segment s's backward fit, with their weight times subtree_carry. A limited
// child cannot turn freely to meet its targets, so their pull must turn its
// parent too; the child's joint point alone cannot, e.g., turn a thigh about
// its long axis to aim a knee hinge. At the child's best angles this is the
// exact direction for the parent (the child's own angle change is second
// order), so the loop approaches the constrained least-squares fit.
//
// The fits need the carried points only through their weighted moments (sum of w d a^T,
// w d, w a and w, with d the desired position and a the point in the fitted segment's
// frame), so each subtree's moments are summed once per backward pass, leaves first, and
// moved into each parent's frame as a whole: the same fits for O(segments) work instead of
// one driver per carried point and ancestor. A subtree's moments are taken before the pass
// moves anything: its segments come after their ancestors in the pass, so each ancestor's
// fit sees them as they stood then, as it would driver by driver.

// Per pass and limited segment, the moments of its own targets (the carry's and the forward
// step's): they stay where they are for the whole solve.
void FabrikSolver::target_moments(std::span<const Eigen::Vector3d> target_world_m) {
  const int n_slots = static_cast<int>(slots_.size());
  for (int pass = 0; pass < pass_count(); ++pass) {
    const double* weight = slot_weight_.data() + static_cast<std::ptrdiff_t>(pass) * n_slots;
    for (int c = 1; c < n_seg_; ++c) {
      if (!limited_[c]) continue;
      Moments& m = own_[static_cast<std::size_t>(pass * n_seg_ + c)];
      m = Moments{};
      for (int k = slot_first_[c]; k < slot_first_[c + 1]; ++k) {
        const int source = slots_[k].source;
        if (weight[k] > 0.0 && source >= 0)
          add_point(m, target_world_m[source] - carry_origin_m_, slots_[k].a_local, weight[k]);
      }
    }
  }
}

// Before a backward pass, per active limited segment: the moments of its own targets and of
// its pulling free children's joints (local_), of its limited children's subtrees in its
// frame (children_), and of its whole carried subtree in its parent's frame (subtree_).
void FabrikSolver::limited_moments(int pass, bool carrying, const Posture& posture) {
  const double* weight =
      slot_weight_.data() + static_cast<std::ptrdiff_t>(pass) * static_cast<int>(slots_.size());
  for (int c = n_seg_ - 1; c > 0; --c) {
    if (!limited_[c] || !active(pass, c)) continue;
    Moments m = own_[static_cast<std::size_t>(pass * n_seg_ + c)];
    for (int k = slot_first_[c]; k < slot_first_[c + 1]; ++k) {
      const int source = slots_[k].source;
      if (weight[k] <= 0.0 || source >= 0 || limited_[~source]) continue;
      add_point(m, posture.segments[~source].base_world_m - carry_origin_m_, slots_[k].a_local,
                weight[k]);
    }
    if (carrying) {
      // Carried, a limited child counts by its subtree's points, not by its joint.
      Moments& below = children_[c];
      below = Moments{};
      carried_children(pass, c, below);
      Moments all = m;
      add(all, below);
      subtree_[c] = all.w > 0.0 ? moved(all, rel_q_[c].toRotationMatrix(),
                                        model_.points[model_.segments[c].parent_point].p_local_m)
                                : Moments{};  // nothing below pulls (orientation targets alone)
    }
    // In its own fit the limited children's joints pull too.
    for (int k = slot_first_[c]; k < slot_first_[c + 1]; ++k) {
      const int source = slots_[k].source;
      if (weight[k] <= 0.0 || source >= 0 || !limited_[~source]) continue;
      add_point(m, posture.segments[~source].base_world_m - carry_origin_m_, slots_[k].a_local,
                weight[k]);
    }
    local_[c] = m;
  }
}

// Adds the subtree moments of s's limited children (in s's frame) to `m`.
void FabrikSolver::carried_children(int pass, int s, Moments& m) const {
  const Segment& seg = model_.segments[s];
  for (int i = 0; i < seg.child_count; ++i) {
    const int g = model_.child_ids[seg.first_child + i];
    if (limited_[g] && active(pass, g)) add(m, subtree_[g]);
  }
}

// For a free segment above limited joints: the carry in its fit (rotate_about_base).
void FabrikSolver::carry_limited(int pass, int s) {
  carried_ = Moments{};
  carried_children(pass, s, carried_);
  const double f = carry_;
  carried_.da *= f;
  carried_.d *= f;
  carried_.a *= f;
  carried_.w *= f;
  carry_on_ = carried_.w > 0.0;
}

// The carried points' alignment about base_m: sum w (d - base) a^T (a in the segment's frame).
Eigen::Matrix3d FabrikSolver::carried_alignment(const Eigen::Vector3d& base_m) const {
  return carried_.da - (base_m - carry_origin_m_) * carried_.a.transpose();
}

// Brings every limited joint of the start posture within its ranges and takes its angles as
// the fits' warm start. Every fit keeps a joint within range and a rider either keeps its
// relative rotation or is brought within range (rider_within_limits), so this one projection keeps
// every joint of the solve within range, even from a start that was not. Out of range, each angle
// goes to its nearer bound (the start has no earlier angle to tell which bound it left through), as
// enforce_joint_limits does; in turns, without trigonometry. A hinge keeps its twist about
// its axis; an off-axis part (a start not from a solve) is dropped.
// Then a base more than 1 nm off its parent's joint goes onto it (else a solve where no pass
// runs returns the gaps); a start a solve left is joined to rounding and is not touched.
void FabrikSolver::prepare_start(Posture& posture) {
  constexpr double kMaxGapM = 1e-9;
  for (int s = 1; s < n_seg_; ++s) {
    if (limited_[s]) within_limits(s, posture);
    Eigen::Vector3d& base_m = posture.segments[s].base_world_m;
    const Eigen::Vector3d joint_m = posture.point_world_m(model_, model_.segments[s].parent_point);
    if ((joint_m - base_m).squaredNorm() > kMaxGapM * kMaxGapM) base_m = joint_m;
  }
}

void FabrikSolver::within_limits(int s, Posture& posture) {
  const Segment& seg = model_.segments[s];
  SegmentPose& pose = posture.segments[s];
  const Eigen::Quaterniond& q_parent = posture.segments[seg.parent].q_world;
  const Eigen::Quaterniond rel = q_parent.conjugate() * pose.q_world;
  const JointArcs& arcs = arcs_[s];
  Turns& turns = turns_[s];
  if (seg.joint.type == JointType::fixed) {
    rel_q_[s] = Eigen::Quaterniond::Identity();
    pose.set_unit_rotation(q_parent);
    return;
  }
  if (hinge_[s]) {
    const Eigen::Vector3d& u = hinge_axis_local_[s];
    const Turn twist = twist_turn(rel, u);
    turns[0] = arcs.clamp(0, twist, twist);
    const Eigen::Quaterniond on_axis = quaternion_about(turns[0], u);
    // Unchanged (to rounding) when the start was a turn about the axis within range.
    const double agree = on_axis.coeffs().dot(rel.coeffs());
    if (agree * agree < 1.0 - 1e-15) pose.set_unit_rotation(q_parent * on_axis);
    rel_q_[s] = q_parent.conjugate() * pose.q_world;
    return;
  }
  turns = joint_turns(s, rel);
  bool inside = true;
  for (int k = 0; k < 3; ++k) inside = inside && arcs.inside(k, turns[k]);
  if (!inside) {
    for (int k = 0; k < 3; ++k) turns[k] = arcs.clamp(k, turns[k], turns[k]);
    pose.set_rotation(q_parent * joint_rotation(s, turns));
  }
  rel_q_[s] = q_parent.conjugate() * pose.q_world;
}

// A limited segment turns through its joint angles alone: its rotation is
// R_parent J_parent E(angles) J_child^T (J: the anatomical frames, E the
// Cardan rotation), so the weighted alignment of its drivers with their
// desired vectors is <E, B> with B = sum_k w_k (parent-frame desired
// vector)(segment joint-frame vector)^T, which fit_joint_angles maximises
// within the ranges (exactly, for a hinge). The base stays where it is.
void FabrikSolver::limited_fit(int s, const Moments& m, const Eigen::Vector3d& base_m,
                               Posture& posture) {
  const Segment& seg = model_.segments[s];
  SegmentPose& pose = posture.segments[s];
  const SegmentPose& parent = posture.segments[seg.parent];
  pose.base_world_m = base_m;
  if (seg.joint.type == JointType::fixed) {
    rel_q_[s] = Eigen::Quaterniond::Identity();  // at rest every frame is the world's
    pose.set_unit_rotation(parent.q_world);
    return;
  }
  // G = sum w (d - base) a^T over the drivers (a in the segment's frame); orientation
  // targets add sum w lever^2 R_d, the same sum over their virtual points (see gather).
  Eigen::Matrix3d g = m.da - (base_m - carry_origin_m_) * m.a.transpose();
  if (orient_on_) g += orient_m_;
  if (hinge_[s]) {
    hinge_fit(s, g, posture);
    return;
  }
  if (seg.joint.type == JointType::ball) {
    // Most of the time a ball joint's free fit lies within its ranges: then
    // it is the constrained fit too, and cheaper to find.
    free_fit(m, g, base_m, pose);
    const Eigen::Quaterniond rel = parent.q_world.conjugate() * pose.q_world;
    const Turns free = joint_turns(s, rel);
    const JointArcs& arcs = arcs_[s];
    if (arcs.inside(0, free[0]) && arcs.inside(1, free[1]) && arcs.inside(2, free[2])) {
      turns_[s] = free;
      rel_q_[s] = rel;
      return;
    }
  }
  // B = P^T W with P = R_parent J_parent and W = G J_child: sum w (d - base) v^T with v the
  // drivers in the joint frame.
  const Eigen::Matrix3d b = (parent.r_world * joint_parent_[s]).transpose() * (g * joint_child_[s]);
  // Warm start from the joint's angles at its last fit (or at the start of the solve).
  Turns& turns = turns_[s];
  fit_joint_turns(b, arcs_[s], turns, kJointSweeps);
  rel_q_[s] = joint_rotation(s, turns).normalized();
  pose.set_unit_rotation(parent.q_world * rel_q_[s]);
}

// A limited ball joint's rotation as if it were free, as rotate_about_base turns a free
// segment, from its drivers' moments: one driver (or the paper's rule), the minimal turn onto
// the mean; else a Newton step of the least-squares rotation.
void FabrikSolver::free_fit(const Moments& m, const Eigen::Matrix3d& g,
                            const Eigen::Vector3d& base_m, SegmentPose& pose) const {
  if (!orient_on_ && m.w > 0.0 && (m.count == 1 || options_.segment_fit == SegmentFit::paper)) {
    const double inv = 1.0 / m.w;
    turn_minimal(pose.r_world * (m.a * inv), m.d * inv + carry_origin_m_ - base_m, pose);
    return;
  }
  fit_rotation_step(g * pose.r_world.transpose(), pose);
}

// True when this level's targets are within tolerance or stopped moving since
// the previous pass of the level.
bool FabrikSolver::level_settled(int pass, std::span<const Eigen::Vector3d> target_world_m,
                                 std::span<const std::uint8_t> visible, const Posture& posture) {
  double max_m = 0.0, change_m = 0.0;
  for (int i = 0; i < targets_.size(); ++i) {
    if (!visible[i] || (options_.use_priorities && targets_.level_index(i) != pass)) continue;
    const double d = (target_point_m(i, posture) - target_world_m[i]).norm();
    max_m = std::max(max_m, d);
    change_m = std::max(change_m, std::abs(d - level_previous_m_[i]));
    level_previous_m_[i] = d;
  }
  for (int k = 0; k < static_cast<int>(orientations_.size()); ++k) {
    if (!orient_visible_[k] || (options_.use_priorities && orient_level_[k] != pass)) continue;
    const std::size_t i = targets_.targets().size() + static_cast<std::size_t>(k);
    const double d = options_.orientation_lever_m *
                     posture.segments[orientations_[k].segment].q_world.angularDistance(orient_q_[k]);
    max_m = std::max(max_m, d);
    change_m = std::max(change_m, std::abs(d - level_previous_m_[i]));
    level_previous_m_[i] = d;
  }
  return max_m <= options_.tolerance_m || change_m <= options_.stall_tolerance_m;
}

SolveResult FabrikSolver::measure(std::span<const Eigen::Vector3d> target_world_m,
                                  std::span<const std::uint8_t> visible, const Posture& posture) {
  const auto point_of = [&](int i) { return target_point_m(i, posture); };
  const std::size_t n_point = targets_.targets().size();
  SolveResult r = targets_.measure_with(point_of, target_world_m, visible,
                                        std::span<double>(distances_m_).first(n_point));
  if (orientations_.empty()) return r;
  double sum_sq = r.rms_m * r.rms_m * r.visible_targets;
  for (std::size_t k = 0; k < orientations_.size(); ++k) {
    double& d = distances_m_[n_point + k];
    if (!orient_visible_[k]) {
      d = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    d = options_.orientation_lever_m *
        posture.segments[orientations_[k].segment].q_world.angularDistance(orient_q_[k]);
    sum_sq += d * d;
    ++r.visible_targets;
    if (d > r.max_m || r.worst_target < 0) {
      r.max_m = d;
      r.worst_target = static_cast<int>(n_point + k);
    }
  }
  if (r.visible_targets > 0) r.rms_m = std::sqrt(sum_sq / r.visible_targets);
  return r;
}

SolveResult FabrikSolver::solve(std::span<const Eigen::Vector3d> target_world_m,
                                std::span<const std::uint8_t> visible, Posture& posture) {
  return solve(target_world_m, visible, {}, {}, posture);
}

SolveResult FabrikSolver::solve(std::span<const Eigen::Vector3d> target_world_m,
                                std::span<const std::uint8_t> visible,
                                std::span<const Eigen::Quaterniond> q_world,
                                std::span<const std::uint8_t> orientation_visible,
                                Posture& posture) {
  if (static_cast<int>(target_world_m.size()) != targets_.size() ||
      static_cast<int>(visible.size()) != targets_.size() ||
      q_world.size() != orientations_.size() || orientation_visible.size() != orientations_.size() ||
      static_cast<int>(posture.segments.size()) != n_seg_) {
    SolveResult mismatch;
    mismatch.status = SolveStatus::size_mismatch;
    return mismatch;
  }
  for (std::size_t k = 0; k < orientations_.size(); ++k) {
    // A rotation that is not finite cannot pull: it counts as not visible.
    orient_visible_[k] = orientation_visible[k] && q_world[k].coeffs().allFinite() &&
                         q_world[k].norm() > 0.5;
    if (!orient_visible_[k]) continue;
    orient_q_[k] = q_world[k].normalized();
    orient_r_[k] = orient_q_[k].toRotationMatrix();
  }
  mark_active(visible);
  prepare_start(posture);
  const Eigen::Vector3d root_pin_m = posture.segments[0].base_world_m;
  carry_origin_m_ = root_pin_m;  // near every point: the carried moments keep their digits
  if (any_limited_) target_moments(target_world_m);
  if (any_link_)
    for (int s = 0; s < n_seg_; ++s)
      if (link_[s]) link_tip_m_[s] = posture.segments[s].to_world(slots_[slot_first_[s]].a_local);
  SolveResult result = measure(target_world_m, visible, posture);
  carry_ = options_.subtree_carry;
  DivergenceWatch divergence(result.rms_m);
  int total_passes = 0, jumps = 0;
  StopRule stop(options_);
  const int passes = pass_count();
  int active_levels = 0, strongest = -1;
  for (int pass = 0; pass < passes; ++pass)
    if (pass_runs(pass)) {
      ++active_levels;
      strongest = pass;
    }
  // One level's error is one number to lower; links keep their rotation apart (turn_links).
  const bool extrapolating = options_.extrapolate && active_levels == 1 && !any_link_;
  if (extrapolating) {
    start_steps(posture);
    previous_step_sq_ = 0.0;
  }
  for (int iteration = 0;; ++iteration) {
    if (iteration == 0 && stop.should_stop(0, distances_m_, previous_m_, result)) {
      if (any_link_) turn_links(posture);
      return result;
    }
    for (int pass = 0; pass < passes; ++pass) {  // weakest level first
      if (!pass_runs(pass)) continue;
      // The strongest level is revisited until it settles, so that it ends
      // each iteration as well met as it can be; with a single level the
      // convergence loop itself repeats the pass.
      const int level_passes = active_levels > 1 && pass == strongest ? options_.level_passes : 1;
      const bool riders = pass_has_riders_[pass] != 0;
      if (riders) std::copy(posture.segments.begin(), posture.segments.end(), start_.begin());
      for (int k = 0; k < level_passes; ++k) {
        forward(pass, target_world_m, visible, posture);
        backward(pass, target_world_m, visible, posture, root_pin_m);
        ++total_passes;
        if (level_passes > 1 && level_settled(pass, target_world_m, visible, posture) && k > 0)
          break;
      }
      if (riders) ride_inactive(pass, posture);
    }
    std::copy(distances_m_.begin(), distances_m_.end(), previous_m_.begin());
    result = measure(target_world_m, visible, posture);
    result.iterations = iteration + 1;
    result.passes = total_passes;
    result.jumps = jumps;
    // SolverOptions::fallback_carry: without the carry the loop can leave a fit it has
    // nearly reached; with it, it approaches the constrained least-squares fit
    // (docs/joint-limits.md, "Subtree carry").
    const bool diverging = divergence.diverging(result.rms_m, result.max_m, options_.tolerance_m) &&
                           carry_ == 0.0 && options_.fallback_carry > 0.0 && any_limited_;
    // The stopping rule judges the iteration before any jump or change of rule: either
    // restarts its rates, so changing when the iteration says the loop is done would cost
    // two more iterations.
    if (stop.should_stop(iteration + 1, distances_m_, previous_m_, result)) {
      if (any_link_) turn_links(posture);
      return result;
    }
    if (diverging) {
      carry_ = options_.fallback_carry;
      stop.jumped();
    }
    if (extrapolating && extrapolate(target_world_m, visible, posture, result)) {
      stop.jumped();
      ++jumps;
    }
  }
}

}  // namespace fabrik
