#include "marker_neighbours.hpp"

#include <cmath>

namespace fabrik {

namespace {

// Distance from a point to the base of segment `child` (a joint of the
// point's own segment or its base), both in the point's segment frame.
double to_joint_m(const Model& model, const Point& p, int child) {
  const Segment& c = model.segments[child];
  if (c.parent == p.segment)  // the joint is a point of ours
    return (p.p_local_m - model.points[c.parent_point].p_local_m).norm();
  return p.p_local_m.norm();  // the joint is our base
}

}  // namespace

MarkerNeighbours::MarkerNeighbours(const Model& model, const std::vector<int>& marker_points) {
  const int n = static_cast<int>(marker_points.size());
  first_.reserve(static_cast<std::size_t>(n) + 1);
  for (int i = 0; i < n; ++i) {
    first_.push_back(static_cast<int>(other_.size()));
    const Point& a = model.points[marker_points[i]];
    for (int j = 0; j < n; ++j) {
      if (j == i) continue;
      const Point& b = model.points[marker_points[j]];
      if (b.segment == a.segment) {
        const double d = (a.p_local_m - b.p_local_m).norm();
        other_.push_back(j), min_m_.push_back(d), max_m_.push_back(d);
        continue;
      }
      // Joined segments: one is the other's parent; the joint is the child's base.
      const int child = model.segments[b.segment].parent == a.segment   ? b.segment
                        : model.segments[a.segment].parent == b.segment ? a.segment
                                                                        : -1;
      if (child < 0) continue;
      const double ra = to_joint_m(model, a, child), rb = to_joint_m(model, b, child);
      other_.push_back(j), min_m_.push_back(std::abs(ra - rb)), max_m_.push_back(ra + rb);
    }
  }
  first_.push_back(static_cast<int>(other_.size()));
}

bool MarkerNeighbours::moved(int i, std::span<const Eigen::Vector3d> measured_m,
                             std::span<const std::uint8_t> visible, double tolerance_m) const {
  int measured = 0, broken = 0;
  for (int k = first_[i]; k < first_[i + 1]; ++k) {
    const int j = other_[k];
    if (!visible[j] || !measured_m[j].allFinite()) continue;
    ++measured;
    const double d = (measured_m[i] - measured_m[j]).norm();
    broken += d < min_m_[k] - tolerance_m || d > max_m_[k] + tolerance_m;
  }
  return measured == 0 || 2 * broken >= measured;
}

}  // namespace fabrik
