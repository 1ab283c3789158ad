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

struct PointSpec {
  std::string name;
  Eigen::Vector3d p_local_m{0, 0, 0};  ///< relative to the segment base, rest frame
  bool marker = false;                 ///< a marker site rather than a joint / end site
};

/// A joint's type and the ranges of the angles it lets move (see JointLimits):
/// radians; ranges of angles the type holds are ignored (held at rest).
struct JointSpec {
  JointType type = JointType::free;
  std::array<double, 3> min_rad{-3.141592653589793, -1.5707963267948966, -3.141592653589793};
  std::array<double, 3> max_rad{3.141592653589793, 1.5707963267948966, 3.141592653589793};
};

struct SegmentSpec {
  std::string name;
  std::string parent;  ///< empty for the root
  std::string base;    ///< name of the base joint: a point of the parent (or the root origin)
  std::vector<PointSpec> points;
  /// Anatomical frame in the rest (world) frame: a rotation matrix whose
  /// columns are its x, y and z axes. Identity when not given.
  Eigen::Matrix3d anatomical = Eigen::Matrix3d::Identity();
  JointSpec joint;  ///< the base joint, relative to the parent
};

/// A named coordinate (see Coordinate): a Cardan angle of `segment`'s
/// anatomical frame relative to `relative_to` (empty: the world), or a world
/// coordinate of `point`.
struct CoordinateSpec {
  std::string name;
  CoordinateKind kind = CoordinateKind::rotation;
  std::string segment, relative_to, point;
  int axis = 0;  ///< x = 0, y = 1, z = 2 (rotation: the Cardan angle about that axis)
  double sign = 1.0;
  double offset = 0.0;  ///< radians or metres, added before the sign
};

/// What went wrong, and where: `segment` indexes the specs (-1: the model as a
/// whole), `point` indexes that segment's points (-1: the segment itself) and
/// `field` names the offending field ("name", "parent", "base", "points",
/// "frame", "joint", or for the model as a whole "coordinates/NAME").
class ModelError : public std::invalid_argument {
 public:
  ModelError(int segment, int point, std::string field, const std::string& what)
      : std::invalid_argument(what), segment_(segment), point_(point), field_(std::move(field)) {}
  int segment() const { return segment_; }
  int point() const { return point_; }
  const std::string& field() const { return field_; }

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
