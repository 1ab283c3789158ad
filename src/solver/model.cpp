#include "model.hpp"

#include <algorithm>

namespace fabrik {

Model::Model(std::string name_, std::vector<Segment> segments_, std::vector<Point> points_,
             std::vector<int> child_ids_, std::vector<Joint> joints_,
             std::vector<Coordinate> coordinates_, const Eigen::Vector3d& root_rest_m_,
             const LabAxes& lab_axes_)
    : name(std::move(name_)),
      segments(std::move(segments_)),
      points(std::move(points_)),
      child_ids(std::move(child_ids_)),
      joints(std::move(joints_)),
      coordinates(std::move(coordinates_)),
      root_rest_m(root_rest_m_),
      lab_axes(lab_axes_) {}

int Model::find_segment(const std::string& segment_name) const {
  for (int i = 0; i < static_cast<int>(segments.size()); ++i)
    if (segments[i].name == segment_name) return i;
  return -1;
}

int Model::find_point(const std::string& point_name) const {
  for (int i = 0; i < static_cast<int>(points.size()); ++i)
    if (points[i].name == point_name) return i;
  return -1;
}

int Model::find_coordinate(const std::string& coordinate_name) const {
  for (int i = 0; i < static_cast<int>(coordinates.size()); ++i)
    if (coordinates[i].name == coordinate_name) return i;
  return -1;
}

int Model::max_points_per_segment() const {
  int n = 0;
  for (const Segment& s : segments) n = std::max(n, s.point_count);
  return n;
}

bool Model::is_ancestor_or_self(int ancestor, int seg) const {
  for (int s = seg; s >= 0; s = segments[s].parent)
    if (s == ancestor) return true;
  return false;
}

std::vector<int> Model::marker_points() const {
  std::vector<int> out;
  for (int i = 0; i < static_cast<int>(points.size()); ++i)
    if (points[i].kind == PointKind::marker) out.push_back(i);
  return out;
}

bool Model::has_joint_limits() const {
  return std::any_of(segments.begin(), segments.end(),
                     [](const Segment& s) { return s.joint.limited(); });
}

}  // namespace fabrik
