// The skeleton model: an immutable tree of rigid segments. All lengths are in
// metres; local coordinates are in the segment's own frame with the segment's
// base joint at the origin. At the rest posture every segment frame is
// parallel to the world frame, so local coordinates are also rest offsets.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace fabrik {

enum class PointKind { base, joint, end_site, marker };

struct Point {
  std::string name;
  int segment = -1;  // owning segment
  PointKind kind = PointKind::end_site;
  Eigen::Vector3d p_local_m{0, 0, 0};  // in the segment frame, relative to its base
  int child_segment = -1;              // for kind == joint: the segment whose base sits here
};

struct Segment {
  std::string name;
  int parent = -1;        // -1 for the root
  int parent_point = -1;  // index into Model::points of the parent's point where our base sits
  int base_point = -1;    // our own base point (local origin)
  int first_point = 0;    // our points are points[first_point, first_point + point_count)
  int point_count = 0;
  int first_child = 0;  // our children are child_ids[first_child, first_child + child_count)
  int child_count = 0;
};

// Joint centres as reported downstream: the root base plus every parent/child link.
struct Joint {
  std::string name;
  int point = -1;  // the child's base point (or the root base)
};

struct Model {
  std::string name;
  std::vector<Segment> segments;  // topological order: a parent precedes its children
  std::vector<Point> points;      // grouped by segment, base point first
  std::vector<int> child_ids;     // children lists, see Segment::first_child
  std::vector<Joint> joints;
  Eigen::Vector3d root_rest_m{0, 0, 0};  // world position of the root base at rest

  int find_segment(const std::string& segment_name) const;
  int find_point(const std::string& point_name) const;
  int max_points_per_segment() const;
  // True if segment `ancestor` is `seg` or lies on the path from `seg` to the root.
  bool is_ancestor_or_self(int ancestor, int seg) const;
  // Indices of every marker point, in model order.
  std::vector<int> marker_points() const;
};

}  // namespace fabrik
