#include "model.hpp"

#include <algorithm>

namespace fabrik {

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

}  // namespace fabrik
