/// @file
/// The skeleton model: an immutable tree of rigid segments. All lengths are in
/// metres; local coordinates are in the segment's own frame with the segment's
/// base joint at the origin. At the rest posture every segment frame is
/// parallel to the world frame, so local coordinates are also rest offsets.
///
/// A Model is made only by build_model (validated) and never changes
/// afterwards: its members are const. Solvers and trackers share it through
/// std::shared_ptr<const Model>.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

/// Prioritized FABRIK inverse kinematics for motion capture: the skeleton model (Model), the
/// solver (SolverPlan, solve), the per-frame tracking pipeline (Tracker) and the loading of its
/// setup (load.hpp). Quantities name their unit: `_m` metres, `_rad` radians, `_s` seconds.
namespace fabrik {

/// What a model point is: `base` is a segment's base joint (its local origin),
/// `joint` a point where a child segment's base sits, `end_site` any other
/// named point of the skeleton, `marker` a marker site.
enum class PointKind { base, joint, end_site, marker };

/// A named point fixed in one segment (rigid: it moves only with its segment).
struct Point {
  std::string name;  ///< unique, except that a child's base point shares its joint's name
  int segment = -1;  ///< owning segment
  PointKind kind = PointKind::end_site;  ///< what the point is (see PointKind)
  Eigen::Vector3d p_local_m{0, 0, 0};    ///< in the segment frame, relative to its base
  int child_segment = -1;                ///< for kind == joint: the segment whose base sits here
};

/// How a segment may turn relative to its parent about its base joint. Its
/// angles are the Cardan decomposition R = Rz(a_z) Rx(a_x) Ry(a_y) of the
/// segment's anatomical frame relative to its parent's: the ISB joint
/// coordinate system (Grood & Suntay 1983; Wu et al. 2002), flexion-extension
/// about the parent's z, ab-adduction about the floating x, axial rotation
/// about the segment's own y. Index 0 is a_z, 1 is a_x, 2 is a_y.
enum class JointType : std::uint8_t {
  free,       ///< no limits (the default)
  ball,       ///< three rotations, each within its range
  universal,  ///< a_z and a_x within their ranges, a_y held at its rest value
  hinge,      ///< a_z within its range, a_x and a_y held: one rotation about the parent's z axis
  fixed,      ///< no rotation relative to the parent
};

/// The limits of a segment's base joint relative to its parent, in the
/// Cardan angles of JointType (index 0: a_z, 1: a_x, 2: a_y).
struct JointLimits {
  JointType type = JointType::free;  ///< which angles move, and whether within ranges
  /// Allowed angles, radians; for an angle the type holds, both are the rest
  /// angle. A moving a_x stays 0.01 rad inside [-pi/2, pi/2]: the Cardan
  /// decomposition is singular at +-pi/2.
  std::array<double, 3> min_rad{-3.141592653589793, -1.5707963267948966, -3.141592653589793};
  /// Upper bounds, radians (see min_rad).
  std::array<double, 3> max_rad{3.141592653589793, 1.5707963267948966, 3.141592653589793};
  std::array<double, 3> rest_rad{0.0, 0.0, 0.0};  ///< the angles at the rest posture
  /// True unless the joint is free (the solver then has limits to enforce).
  bool limited() const { return type != JointType::free; }
};

/// One rigid body of the skeleton: its place in the tree, its points and the
/// limits of its base joint. Indices are into the Model's vectors.
struct Segment {
  std::string name;       ///< unique within the model
  int parent = -1;        ///< -1 for the root
  int parent_point = -1;  ///< index into Model::points of the parent's point where our base sits
  int base_point = -1;    ///< our own base point (local origin)
  int first_point = 0;    ///< our points are points[first_point, first_point + point_count)
  int point_count = 0;    ///< number of points, the base point included
  int first_child = 0;    ///< our children are child_ids[first_child, first_child + child_count)
  int child_count = 0;    ///< number of child segments
  /// The anatomical frame (x anterior, y superior/proximal, z right, as ISB
  /// recommends) in the segment frame, i.e. its axes in the world at rest.
  /// Identity when the model does not define one.
  Eigen::Quaterniond q_anatomical{Eigen::Quaterniond::Identity()};
  JointLimits joint;  ///< of the base joint, relative to the parent (the root has none)
};

/// Joint centres as reported downstream: the root base plus every parent/child link.
struct Joint {
  std::string name;  ///< the point's name (the base joint's name in the model description)
  int point = -1;    ///< the child's base point (or the root base)
};

/// A named quantity computed from a posture, as OpenSim's coordinates are:
/// one Cardan angle of a segment's anatomical frame relative to another's
/// (or to the world), or one world coordinate of a point.
enum class CoordinateKind : std::uint8_t { rotation, translation };

/// One named coordinate of the model (see CoordinateKind); coordinate_values
/// computes them all. Which fields apply depends on `kind`.
struct Coordinate {
  std::string name;                                ///< unique within the model
  CoordinateKind kind = CoordinateKind::rotation;  ///< an angle (radians) or a position (metres)
  int segment = -1;                                ///< rotation: the moving segment
  int relative_to = -1;  ///< rotation: the reference segment, -1 for the world
  int angle = 0;         ///< rotation: Cardan angle index (0: a_z, 1: a_x, 2: a_y)
  int point = -1;        ///< translation: the point
  int axis = 0;          ///< translation: world axis (0: x, 1: y, 2: z)
  double sign = 1.0;     ///< value = sign * (raw + offset)
  double offset = 0.0;   ///< radians or metres
};

/// The lab's axes: how the world the marker positions are given in (the
/// lab's frame) lies relative to the reference frame of world-relative
/// coordinates, OpenSim's ground: X forward, Y up, Z = X x Y (right). Each
/// is a signed lab axis, unit, at right angles. Positions stay in the lab's
/// frame; only coordinates relative to the world are expressed in the
/// reference frame. The default, Y up and X forward, is the identity.
struct LabAxes {
  Eigen::Vector3d up_lab{0, 1, 0};       ///< the lab axis that points up (the reference's Y)
  Eigen::Vector3d forward_lab{1, 0, 0};  ///< the lab axis that points forward (the reference's X)
  /// Rows: the reference's X, Y, Z axes in the lab; a lab vector v is
  /// r_reference_lab() * v in the reference frame.
  Eigen::Matrix3d r_reference_lab() const {
    Eigen::Matrix3d r;
    r.row(0) = forward_lab.transpose();
    r.row(1) = up_lab.transpose();
    r.row(2) = forward_lab.cross(up_lab).transpose();
    return r;
  }
  /// The rotation that takes a vector in `from`'s axes into these: from's up to
  /// this up, from's forward to this forward (a server's or a lab's axes to
  /// the lab's or a view's).
  Eigen::Matrix3d r_from(const LabAxes& from) const {
    return r_reference_lab().transpose() * from.r_reference_lab();
  }
  /// Same axes, compared exactly.
  bool operator==(const LabAxes& o) const {
    return up_lab == o.up_lab && forward_lab == o.forward_lab;
  }
};

/// The skeleton: segments in topological order, their points, the joints
/// reported downstream and the named coordinates. Made by build_model only;
/// immutable (see the file's description).
class Model {
 public:
  const std::string name;               ///< the model's name (e.g. from its description file)
  const std::vector<Segment> segments;  ///< topological order: a parent precedes its children
  const std::vector<Point> points;      ///< grouped by segment, base point first
  const std::vector<int> child_ids;     ///< children lists, see Segment::first_child
  const std::vector<Joint> joints;      ///< the root base first, then one per parent/child link
  const std::vector<Coordinate> coordinates;  ///< named coordinates, in the description's order
  const Eigen::Vector3d root_rest_m;          ///< world position of the root base at rest
  const LabAxes lab_axes;                     ///< for coordinates relative to the world

  /// Index into segments of the segment with this name, -1 if none.
  int find_segment(const std::string& segment_name) const;
  /// Index into points of the point with this name, -1 if none. A joint's name is also its
  /// child's base point: the parent's point (it comes first) is returned.
  int find_point(const std::string& point_name) const;
  /// Index into coordinates of the coordinate with this name, -1 if none.
  int find_coordinate(const std::string& coordinate_name) const;
  /// The largest Segment::point_count (sizes per-segment scratch space).
  int max_points_per_segment() const;
  /// True if segment `ancestor` is `seg` or lies on the path from `seg` to the root.
  bool is_ancestor_or_self(int ancestor, int seg) const;
  /// Indices of every marker point, in model order.
  std::vector<int> marker_points() const;
  /// True if any segment's joint has limits.
  bool has_joint_limits() const;

 private:
  friend class ModelAssembly;
  Model(std::string name, std::vector<Segment> segments, std::vector<Point> points,
        std::vector<int> child_ids, std::vector<Joint> joints, std::vector<Coordinate> coordinates,
        const Eigen::Vector3d& root_rest_m, const LabAxes& lab_axes);
};

}  // namespace fabrik
