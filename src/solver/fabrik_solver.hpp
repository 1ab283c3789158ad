// Prioritized FABRIK on a tree of rigid segments (Moya & Colloud 2013, built
// on Aristidou & Lasenby 2011). Every iteration of the convergence loop runs
// the priority loop, weakest level first; each level does one forward
// reaching pass (leaves to root) and one backward pass (root to leaves) with
// that level's targets only, so the last, strongest level is best fulfilled.
//
// The solver is one thread's workspace over a shared, immutable FabrikPlan
// (fabrik_plan.hpp): the plan's tables are not copied per solver. solve()
// never allocates: all scratch space is sized in the constructor.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "fabrik_plan.hpp"
#include "joint_fit.hpp"
#include "link_step.hpp"
#include "model.hpp"
#include "posture.hpp"
#include "solve_types.hpp"
#include "target_set.hpp"

namespace fabrik {

class FabrikSolver {
 public:
  // Weighted moments of points pulled towards desired positions: sum of w d a^T, w d, w a
  // and w (d from an origin, a in a segment's frame), for the subtree carry.
  struct Moments {
    Eigen::Matrix3d da = Eigen::Matrix3d::Zero();
    Eigen::Vector3d d = Eigen::Vector3d::Zero(), a = Eigen::Vector3d::Zero();
    double w = 0.0;
    int count = 0;  // points
  };

  // A workspace for a plan other solvers may share (read-only, from any thread).
  FabrikSolver(std::shared_ptr<const FabrikPlan> plan, SolverOptions options);
  // The same over a plan of its own; the solver shares ownership of the (immutable) model.
  FabrikSolver(std::shared_ptr<const Model> model, std::vector<Target> targets,
               SolverOptions options, std::vector<OrientationTarget> orientations = {});
  // The same with a copy of `model`.
  FabrikSolver(const Model& model, std::vector<Target> targets, SolverOptions options,
               std::vector<OrientationTarget> orientations = {});

  // target_world_m[i] and visible[i] belong to targets()[i]. `posture` is the
  // start (warm start: the previous frame's result) and receives the result.
  // Inputs of the wrong size give SolveStatus::size_mismatch (posture unchanged).
  // Joints with limits (Segment::joint) end every solve within them.
  SolveResult solve(std::span<const Eigen::Vector3d> target_world_m,
                    std::span<const std::uint8_t> visible, Posture& posture);
  // The same with orientation targets: q_world[k] (the segment's desired
  // world rotation, unit) and orientation_visible[k] belong to orientations()[k].
  SolveResult solve(std::span<const Eigen::Vector3d> target_world_m,
                    std::span<const std::uint8_t> visible,
                    std::span<const Eigen::Quaterniond> q_world,
                    std::span<const std::uint8_t> orientation_visible, Posture& posture);

  const std::shared_ptr<const FabrikPlan>& plan() const { return plan_; }
  const std::vector<Target>& targets() const { return targets_.targets(); }
  const std::vector<OrientationTarget>& orientations() const { return plan_->orientations; }
  const SolverOptions& options() const { return options_; }
  void set_options(const SolverOptions& options) {
    options_ = options;
    marked_ = false;  // the marks depend on the options
  }
  // Per point target, a factor on its weight for the solves that follow (a marker's
  // confidence); all 1 until set. Same size as targets(), else ignored. Allocates nothing.
  void set_weight_scale(std::span<const double> scale);
  // Distance of each target to its point after the last solve (NaN if not
  // visible): point targets, then orientation targets (angle times lever).
  std::span<const double> target_distances_m() const { return distances_m_; }

 private:
  using Slot = FabrikPlan::Slot;
  struct Driver {  // one point of a segment pulled towards a position
    const Slot* slot;
    const Eigen::Vector3d* desired;
    double weight;
    const Eigen::Vector3d& a_local() const { return slot->a_local; }  // relative to the base
    const Eigen::Vector3d& d_world() const { return *desired; }       // where it should go
    double a_norm_m() const { return slot->a_norm_m; }
  };

  // Marks the active segments and sets every slot's weight in every pass.
  void mark_active(std::span<const std::uint8_t> visible);
  // Per pass and segment: kOwn if the subtree has a visible target of the
  // pass's level, kAnchor if it has one of a stronger level.
  static constexpr std::uint8_t kOwn = 1, kAnchor = 2;
  bool active(int pass, int s) const { return active_[pass * n_seg_ + s] != 0; }
  std::uint8_t activity(int pass, int s) const { return active_[pass * n_seg_ + s]; }
  // Passes of the priority loop, and whether one runs: its level has a visible target.
  int pass_count() const { return options_.use_priorities ? n_pass_ : 1; }
  bool pass_runs(int pass) const { return (activity(pass, 0) & kOwn) != 0; }
  // The weight a target has in a pass: 0 if it does not take part.
  double pass_weight(int pass, int target) const;
  int gather(int pass, int s, std::span<const Eigen::Vector3d> target_world_m,
             std::span<const std::uint8_t> visible, const Posture& posture);
  void forward(int pass, std::span<const Eigen::Vector3d> target_world_m,
               std::span<const std::uint8_t> visible, Posture& posture);
  // Leaves the segments inactive in the pass where they are, for ride_inactive.
  void backward(int pass, std::span<const Eigen::Vector3d> target_world_m,
                std::span<const std::uint8_t> visible, Posture& posture,
                const Eigen::Vector3d& root_pin_m);
  void ride_inactive(int pass, Posture& posture);
  // Segment s turned with its parent since the level's passes began (start_), as it was.
  void ride_on_parent(int s, Posture& posture) const {
    const int parent = model_.segments[s].parent;
    posture.segments[s].set_rotation(posture.segments[parent].q_world *
                                     (start_[parent].q_world.conjugate() * start_[s].q_world));
  }
  // Where segment s's base is, from its parent as it stands (a link parent's one slot is
  // this segment's joint).
  Eigen::Vector3d joint_world_m(int s, const Posture& posture) const {
    const Segment& seg = model_.segments[s];
    return link_[seg.parent] ? link_tip_m_[seg.parent]
                             : posture.point_world_m(model_, seg.parent_point);
  }
  bool level_settled(int pass, std::span<const Eigen::Vector3d> target_world_m,
                     std::span<const std::uint8_t> visible, const Posture& posture);
  void place_with_candidates(int n, SegmentPose& pose, bool turn) const;
  // Where a slot's point is pulled: its target, or its child segment's base.
  const Eigen::Vector3d& desired_m(const Slot& slot,
                                   std::span<const Eigen::Vector3d> target_world_m,
                                   const Posture& posture) const {
    return slot.source >= 0 ? target_world_m[slot.source]
                            : posture.segments[~slot.source].base_world_m;
  }
  // Links: see mark_active.
  void forward_link(int s, std::span<const Eigen::Vector3d> target_world_m, Posture& posture,
                    LinkStep& last) const;
  void backward_link(int s, const Eigen::Vector3d& base_m,
                     std::span<const Eigen::Vector3d> target_world_m, Posture& posture,
                     LinkStep& last, bool chained);
  void turn_links(Posture& posture) const;
  // World position of target i's point during a solve.
  Eigen::Vector3d target_point_m(int i, const Posture& posture) const {
    const int s = target_segment_[i];
    return link_[s] ? link_tip_m_[s] : posture.point_world_m(model_, targets_.targets()[i].point);
  }
  void free_root_fit(int n, SegmentPose& pose) const;
  // Distances of every target (points, then orientations) and their summary.
  SolveResult measure(std::span<const Eigen::Vector3d> target_world_m,
                      std::span<const std::uint8_t> visible, const Posture& posture);
  bool orientation_visible(int k) const { return orient_visible_[k] != 0; }
  // A segment with a limited base joint: the rotation within its ranges that
  // best aims its drivers, about a given base.
  void limited_fit(int s, const Moments& m, const Eigen::Vector3d& base_m, Posture& posture);
  void free_fit(const Moments& m, const Eigen::Matrix3d& g, const Eigen::Vector3d& base_m,
                SegmentPose& pose) const;
  void hinge_fit(int s, const Eigen::Matrix3d& g, Posture& posture);
  void gather_orientations(int pass, int s);

  void prepare_start(Posture& posture);               // within range, connected
  void within_limits(int s, Posture& posture);        // one limited segment of the start
  void rider_within_limits(int s, Posture& posture);  // one limited rider (ride_inactive)
  // J_parent E(turns) J_child^T, a limited joint's rotation relative to its parent from its
  // Cardan turns (J: the anatomical frames), and the turns of such a rotation.
  Eigen::Quaterniond joint_rotation(int s, const Turns& turns) const {
    const Segment& seg = model_.segments[s];
    return model_.segments[seg.parent].q_anatomical * quaternion_zxy(turns) *
           seg.q_anatomical.conjugate();
  }
  Turns joint_turns(int s, const Eigen::Quaterniond& rel) const {
    const Segment& seg = model_.segments[s];
    return turns_zxy((model_.segments[seg.parent].q_anatomical.conjugate() * rel * seg.q_anatomical)
                         .toRotationMatrix());
  }
  // The subtree carry's points as moments (fabrik_solver.cpp, "subtree_carry").
  void target_moments(std::span<const Eigen::Vector3d> target_world_m);
  void limited_moments(int pass, bool carrying, const Posture& posture);
  void carried_children(int pass, int s, Moments& m) const;
  void carry_limited(int pass, int s);
  Eigen::Matrix3d carried_alignment(const Eigen::Vector3d& base_m) const;
  std::vector<Moments> own_;    // [pass][segment]: a limited segment's targets, in its frame
  std::vector<Moments> local_;  // per limited segment, per backward pass: targets and free children
  std::vector<Moments> children_;  // and its limited children's subtrees, in its frame
  std::vector<Moments> subtree_;  // per limited segment: its carried subtree, in its parent's frame
  Moments carried_;               // the carry into the segment being fitted, in its frame
  bool carry_on_ = false;         // the fit includes carried_
  // This solve's carry factor: options_.subtree_carry, or options_.fallback_carry once the
  // loop diverges without it (solve()).
  double carry_ = 0.0;
  Eigen::Vector3d carry_origin_m_ = Eigen::Vector3d::Zero();  // the moments' d are from here
  void forward_limited(int pass, int s, Posture& posture) const;
  // SolverOptions::extrapolate (fabrik_extrapolation.cpp).
  bool extrapolate(std::span<const Eigen::Vector3d> target_world_m,
                   std::span<const std::uint8_t> visible, Posture& posture, SolveResult& result);
  void start_steps(const Posture& posture);
  void record_step(const Posture& posture, double& step_sq, double& dot);
  double weighted_error_m2() const;
  Eigen::Quaterniond relative_rotation(int s, const Posture& posture) const;
  // A jump goes at most this many times the last step ahead, and only after two steps whose
  // directions agree to this cosine and whose sizes shrink by at least kMinRate.
  static constexpr double kMaxJump = 3.0;
  static constexpr double kMinAlignment = 0.9;
  static constexpr double kMinRate = 0.5;
  Posture jump_;  // scratch: the jumped posture
  std::vector<Turns> jump_turns_,
      step_turns_;                // per segment: jumped turns, turns after the last step
  std::vector<Turns> step_turn_;  // per segment: the last step's change of each turn
  std::vector<Eigen::Quaterniond> jump_rel_q_, step_rel_q_;
  std::vector<Eigen::Vector3d> last_step_m_;  // per segment: the last step (see record_step)
  Eigen::Vector3d step_base_m_ = Eigen::Vector3d::Zero(),
                  last_base_step_m_ = Eigen::Vector3d::Zero();
  double previous_step_sq_ = 0.0;
  int steps_recorded_ = 0;
  std::vector<double> jump_distances_m_;
  void rotate_about_base(int n, const Eigen::Vector3d& base_m, SegmentPose& pose) const;

  // The plan, and views of its parts (fabrik_plan.hpp), all read-only. Spans, not references
  // to the vectors: an element is one load from the solver as before, not two.
  std::shared_ptr<const FabrikPlan> plan_;
  const Model& model_;
  const TargetSet& targets_;
  const int n_seg_;
  const int n_pass_;  // priority levels (without priorities, pass_count() is 1)
  const bool any_limited_;
  const std::span<const Slot> slots_;
  const std::span<const int> slot_first_;
  const std::span<const int> target_segment_;
  const std::span<const std::uint8_t> limited_, parent_of_limited_;
  const std::span<const Eigen::Matrix3d> joint_parent_, joint_child_;
  const std::span<const JointArcs> arcs_;
  const std::span<const std::uint8_t> hinge_;
  const std::span<const Eigen::Vector3d> hinge_axis_local_;
  const std::span<const OrientationTarget> orientations_;
  const std::span<const int> orient_level_, orient_first_, orient_by_segment_;
  const std::span<const std::uint8_t> has_orientation_;

  SolverOptions options_;
  std::vector<std::uint8_t> active_;  // [pass][segment]: a visible target in the subtree
  std::vector<Driver> drivers_;       // scratch for one segment
  std::vector<double> weight_scale_;  // per point target: set_weight_scale's factors
  std::vector<double> slot_weight_;  // [pass][slot], per solve: 0 when it does not take part
  std::vector<std::uint8_t> pass_has_riders_;  // per pass, per solve: an inactive non-root segment
  std::vector<std::uint8_t> driven_;           // per segment, per solve: active in a pass that runs
  // What the marks above were computed for: skipped when a frame has the same
  // visibility and options as the previous one (the usual case in a stream).
  std::vector<std::uint8_t> marked_visible_, marked_orient_visible_;
  bool marked_ = false;
  // Links, per marking: segments that one point alone drives in every pass
  // (classic FABRIK links). During a solve only that point's world position
  // (link_tip_m_) moves; the rotation is set once, when the solve ends.
  std::vector<std::uint8_t> link_;
  bool any_link_ = false;
  std::vector<Eigen::Vector3d> link_tip_m_;
  // A hinge's turns_[s][0] and arcs_[s] are its angle from rest.
  std::vector<Turns> turns_;  // per limited segment: its joint angles at its latest fit
  std::vector<Eigen::Quaterniond> rel_q_;  // and its rotation relative to the parent then
  std::vector<SegmentPose> start_;   // posture at the start of a level's passes
  std::vector<double> distances_m_, previous_m_;
  std::vector<double> level_previous_m_;  // per target, between passes of one level
  // Orientation targets: per-pass weights, and per solve their desired
  // rotations and visibility. gather() sums the terms that take part in a
  // pass for one segment: sum of w lever^2 R_desired.
  std::vector<double> orient_weight_;  // [pass][orientation target]
  std::vector<Eigen::Matrix3d> orient_r_;
  std::vector<Eigen::Quaterniond> orient_q_;
  std::vector<std::uint8_t> orient_visible_;
  Eigen::Matrix3d orient_m_ = Eigen::Matrix3d::Zero();
  bool orient_on_ = false;
};

}  // namespace fabrik
