/// @file
/// Builds a validated Model from a plain description (used by the JSON loader,
/// the built-in models and the tests). Throws ModelError at setup time only.
#pragma once

#include <Eigen/Core>
#include <array>
#include <stdexcept>
#include <string>
#include <vector>

#include "model.hpp"

namespace fabrik {

/// A point of a segment as described: where it sits and whether it is a marker.
/// A point named as another segment's base becomes the joint to that child.
struct PointSpec {
  std::string name;                    ///< unique across the whole model
  Eigen::Vector3d p_local_m{0, 0, 0};  ///< relative to the segment base, rest frame
  bool marker = false;                 ///< a marker site rather than a joint / end site
};

/// A joint's type and the ranges of the angles it lets move (see JointLimits):
/// radians; ranges of angles the type holds are ignored (held at rest).
struct JointSpec {
  JointType type = JointType::free;  ///< which angles move (see JointType)
  /// Lower bounds of (a_z, a_x, a_y), radians.
  std::array<double, 3> min_rad{-3.141592653589793, -1.5707963267948966, -3.141592653589793};
  /// Upper bounds of (a_z, a_x, a_y), radians.
  std::array<double, 3> max_rad{3.141592653589793, 1.5707963267948966, 3.141592653589793};
};

/// One segment as described: its name, where it hangs in the tree, its points,
/// its anatomical frame and its base joint.
struct SegmentSpec {
  std::string name;    ///< unique, not empty
  std::string parent;  ///< empty for the root
  std::string base;    ///< name of the base joint: a point of the parent (or the root origin)
  std::vector<PointSpec> points;  ///< its points other than the base, in its rest frame
  /// Anatomical frame in the rest (world) frame: a rotation matrix whose
  /// columns are its x, y and z axes. Identity when not given.
  Eigen::Matrix3d anatomical = Eigen::Matrix3d::Identity();
  JointSpec joint;  ///< the base joint, relative to the parent
};

/// A named coordinate (see Coordinate): a Cardan angle of `segment`'s
/// anatomical frame relative to `relative_to` (empty: the world), or a world
/// coordinate of `point`.
struct CoordinateSpec {
  std::string name;                                ///< unique, not empty
  CoordinateKind kind = CoordinateKind::rotation;  ///< an angle or a position
  /// Rotation: the name of the moving segment.
  std::string segment, relative_to, point;
  /// @var relative_to
  /// Rotation: the name of the reference segment, empty for the world.
  /// @var point
  /// Translation: the name of the point.
  int axis = 0;         ///< x = 0, y = 1, z = 2 (rotation: the Cardan angle about that axis)
  double sign = 1.0;    ///< value = sign * (raw + offset); finite, not 0
  double offset = 0.0;  ///< radians or metres, added before the sign
};

/// What went wrong, and where: `segment` indexes the specs (-1: the model as a
/// whole), `point` indexes that segment's points (-1: the segment itself) and
/// `field` names the offending field ("name", "parent", "base", "points",
/// "frame", "joint", or for the model as a whole "coordinates/NAME").
class ModelError : public std::invalid_argument {
 public:
  /// `what` is the message (std::exception::what).
  ModelError(int segment, int point, std::string field, const std::string& what)
      : std::invalid_argument(what), segment_(segment), point_(point), field_(std::move(field)) {}
  int segment() const { return segment_; }  ///< index into the specs, -1: the model as a whole
  int point() const { return point_; }      ///< index into that segment's points, -1: the segment
  const std::string& field() const { return field_; }  ///< the offending field's name

 private:
  int segment_;
  int point_;
  std::string field_;
};

/// `lab_axes` must be two lab axes at right angles (ModelError, field "lab_axes").
Model build_model(const std::string& name, const std::vector<SegmentSpec>& specs,
                  const Eigen::Vector3d& root_rest_m,
                  const std::vector<CoordinateSpec>& coordinates = {},
                  const LabAxes& lab_axes = {});

/// The same model with every joint free (for comparisons: limits on and off).
Model without_joint_limits(const Model& model);

}  // namespace fabrik
