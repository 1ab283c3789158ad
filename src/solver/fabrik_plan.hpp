// The fixed half of a prioritized FABRIK solve (Pinocchio's Model to the
// solver's Data): which points of which segments are pulled, the priority
// levels, the joints' limits as the fits use them. Derived once from the
// model, the targets and the orientation targets; read-only afterwards, so
// one plan is shared by every FabrikSolver (one per thread) that solves it.
// Per-solve state (marks, weights, moments, steps) is the solver's own.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <vector>

#include "joint_fit.hpp"
#include "model.hpp"
#include "solve_types.hpp"
#include "target_set.hpp"

namespace fabrik {

struct FabrikPlan {
  // Throws std::invalid_argument for a target or orientation target the model
  // cannot hold (TargetSet's checks, a segment out of range, a bad weight).
  FabrikPlan(std::shared_ptr<const Model> model, std::vector<Target> targets,
             std::vector<OrientationTarget> orientations);
  FabrikPlan(const FabrikPlan&) = delete;  // `model` refers into model_holder
  FabrikPlan& operator=(const FabrikPlan&) = delete;

  // A point of a segment that may drive it: one of its targets or the joint
  // of one of its children. Grouped by segment.
  struct Slot {
    Eigen::Vector3d a_local;
    double a_norm_m;
    int source;  // target index if >= 0, else child segment ~source
  };

  std::shared_ptr<const Model> model_holder;
  const Model& model;
  TargetSet targets;
  std::vector<OrientationTarget> orientations;
  int n_seg = 0;
  int n_pass = 1;       // priority levels (at least 1)
  int max_drivers = 0;  // the most slots one segment has
  std::vector<Slot> slots;  // by segment: slots[slot_first[s], slot_first[s + 1])
  std::vector<int> slot_first;
  std::vector<int> target_segment;  // the segment of each target's point
  // Orientation targets by segment (orient_first[s] .. orient_first[s + 1] into
  // orient_by_segment), and each one's level index.
  std::vector<int> orient_level, orient_first, orient_by_segment;
  std::vector<std::uint8_t> has_orientation;  // per segment
  // Joint limits: per segment, whether its base joint is limited or it is the
  // parent of a limited joint (then never a link: the child's limit needs its
  // full rotation), and the anatomical frames of both sides.
  std::vector<std::uint8_t> limited, parent_of_limited;
  bool any_limited = false;
  std::vector<Eigen::Matrix3d> joint_parent, joint_child;
  std::vector<JointArcs> arcs;  // per segment; a hinge's as turns from rest
  // Hinges: the axis, in the parent's frame (at rest the child's frame is the parent's).
  std::vector<std::uint8_t> hinge;
  std::vector<Eigen::Vector3d> hinge_axis_local;
};

}  // namespace fabrik
