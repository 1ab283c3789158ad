/// @file
/// A posture: the world pose of every segment. Point positions follow from it,
/// so segment geometry is rigid by construction (only rotation and translation
/// are ever changed, and rotations are kept unit quaternions).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <limits>
#include <span>
#include <vector>

#include "model.hpp"

namespace fabrik {

/// The world pose of one segment: its frame's rotation and its base's position.
struct SegmentPose {
  Eigen::Quaterniond q_world{Eigen::Quaterniond::Identity()};  ///< segment frame -> world
  Eigen::Matrix3d r_world{Eigen::Matrix3d::Identity()};        ///< cached q_world
  Eigen::Vector3d base_world_m{0, 0, 0};                       ///< world position of the base

  /// Sets the rotation (segment frame -> world) to `q` normalised, and its cached matrix.
  void set_rotation(const Eigen::Quaterniond& q) {
    q_world = q.normalized();
    r_world = q_world.toRotationMatrix();
  }
  /// For a quaternion already normalised by the caller (skips a second normalisation).
  void set_unit_rotation(const Eigen::Quaterniond& q) {
    q_world = q;
    r_world = q_world.toRotationMatrix();
  }
  /// World position (metres) of a point given in the segment frame, relative to the base.
  Eigen::Vector3d to_world(const Eigen::Vector3d& p_local_m) const {
    return r_world * p_local_m + base_world_m;
  }
};

/// The world pose of every segment of one model.
struct Posture {
  std::vector<SegmentPose> segments;  ///< one per Model::segments, in the model's order

  /// The model's rest posture: every frame parallel to world, joints connected.
  static Posture rest(const Model& model);
  /// World position (metres) of model point `point` (an index into Model::points); NaN for
  /// an index out of range or a posture of another model.
  Eigen::Vector3d point_world_m(const Model& model, int point) const {
    if (point < 0 || static_cast<std::size_t>(point) >= model.points.size())
      return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    const Point& p = model.points[static_cast<std::size_t>(point)];
    if (p.segment < 0 || static_cast<std::size_t>(p.segment) >= segments.size())
      return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    return segments[static_cast<std::size_t>(p.segment)].to_world(p.p_local_m);
  }
};

/// Places every non-root segment's base on its parent's joint point, keeping
/// rotations: used after rotations change (kinematics, baselines). False, and the posture
/// unchanged, when it has not one pose per segment of the model.
bool connect_joints(const Model& model, Posture& posture);

/// Forward kinematics: world rotations from rotations relative to the parent
/// (q_local[0] is the root's world rotation), bases connected at the joints. False, and the
/// posture unchanged, when q_local or the posture has not one entry per segment.
bool set_from_local(const Model& model, const Eigen::Vector3d& root_base_m,
                    std::span<const Eigen::Quaterniond> q_local, Posture& posture);

}  // namespace fabrik
