#include "fabrik_plan.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace fabrik {

namespace {
std::vector<int> levels_of(const std::vector<OrientationTarget>& orientations) {
  std::vector<int> levels;
  for (const OrientationTarget& o : orientations) levels.push_back(o.level);
  return levels;
}
const std::shared_ptr<const Model>& not_null(const std::shared_ptr<const Model>& model) {
  if (!model) throw std::invalid_argument("solver plan: no model");
  return model;
}
}  // namespace

FabrikPlan::FabrikPlan(std::shared_ptr<const Model> model_ptr, std::vector<Target> targets_in,
                       std::vector<OrientationTarget> orientations_in)
    : model_holder(not_null(model_ptr)),
      model(*model_holder),
      targets(model, std::move(targets_in), levels_of(orientations_in)),
      orientations(std::move(orientations_in)),
      n_seg(static_cast<int>(model.segments.size())),
      n_pass(std::max<int>(1, static_cast<int>(targets.levels().size()))) {
  for (int s = 0; s < n_seg; ++s)
    max_drivers = std::max(max_drivers, static_cast<int>(targets.on_segment(s).size()) +
                                            model.segments[s].child_count);
  slot_first.assign(static_cast<std::size_t>(n_seg + 1), 0);
  for (int s = 0; s < n_seg; ++s) {
    slot_first[s] = static_cast<int>(slots.size());
    for (int t : targets.on_segment(s)) {
      const Eigen::Vector3d& a = model.points[targets.targets()[t].point].p_local_m;
      slots.push_back({a, a.norm(), t});
    }
    const Segment& seg = model.segments[s];
    for (int k = 0; k < seg.child_count; ++k) {
      const int c = model.child_ids[seg.first_child + k];
      const Eigen::Vector3d& a = model.points[model.segments[c].parent_point].p_local_m;
      slots.push_back({a, a.norm(), ~c});
    }
  }
  slot_first[n_seg] = static_cast<int>(slots.size());
  for (const Target& t : targets.targets()) target_segment.push_back(model.points[t.point].segment);

  has_orientation.assign(static_cast<std::size_t>(n_seg), 0);
  orient_first.assign(static_cast<std::size_t>(n_seg + 1), 0);
  for (const OrientationTarget& o : orientations) {
    if (o.segment < 0 || o.segment >= n_seg)
      throw std::invalid_argument("orientation target segment index out of range");
    if (!(o.weight > 0.0) || !std::isfinite(o.weight))
      throw std::invalid_argument("orientation target weight must be positive and finite");
    orient_level.push_back(targets.index_of_level(o.level));
    has_orientation[o.segment] = 1;
  }
  for (int s = 0; s < n_seg; ++s) {
    orient_first[s] = static_cast<int>(orient_by_segment.size());
    for (int k = 0; k < static_cast<int>(orientations.size()); ++k)
      if (orientations[k].segment == s) orient_by_segment.push_back(k);
  }
  orient_first[n_seg] = static_cast<int>(orient_by_segment.size());

  limited.assign(static_cast<std::size_t>(n_seg), 0);
  parent_of_limited.assign(static_cast<std::size_t>(n_seg), 0);
  joint_parent.assign(static_cast<std::size_t>(n_seg), Eigen::Matrix3d::Identity());
  joint_child.assign(static_cast<std::size_t>(n_seg), Eigen::Matrix3d::Identity());
  for (const Segment& seg : model.segments) {
    if (seg.joint.type != JointType::hinge) {
      arcs.emplace_back(seg.joint);
      continue;
    }
    // A hinge's range as turns about its axis from rest (the angle it fits).
    JointLimits from_rest = seg.joint;
    from_rest.min_rad[0] -= seg.joint.rest_rad[0];
    from_rest.max_rad[0] -= seg.joint.rest_rad[0];
    from_rest.rest_rad[0] = 0.0;
    arcs.emplace_back(from_rest);
  }
  for (int s = 1; s < n_seg; ++s) {
    const Segment& seg = model.segments[s];
    if (!seg.joint.limited()) continue;
    limited[s] = 1;
    any_limited = true;
    parent_of_limited[seg.parent] = 1;
    joint_parent[s] = model.segments[seg.parent].q_anatomical.toRotationMatrix();
    joint_child[s] = seg.q_anatomical.toRotationMatrix();
  }
  hinge.assign(static_cast<std::size_t>(n_seg), 0);
  hinge_axis_local.assign(static_cast<std::size_t>(n_seg), Eigen::Vector3d::UnitZ());
  for (int s = 1; s < n_seg; ++s) {
    if (model.segments[s].joint.type != JointType::hinge) continue;
    hinge[s] = 1;
    // At rest the child's frame is the parent's: one local axis serves both.
    hinge_axis_local[s] = joint_parent[s].col(2);
  }
}

}  // namespace fabrik
