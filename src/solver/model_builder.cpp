#include "model_builder.hpp"

#include <map>
#include <set>

namespace fabrik {

namespace {
constexpr double kMinExtentM = 1e-9;

std::string quoted(const std::string& s) {
  return "'" + s + "'";
}
}  // namespace

Model build_model(const std::string& name, const std::vector<SegmentSpec>& specs,
                  const Eigen::Vector3d& root_rest_m) {
  if (specs.empty()) throw ModelError(-1, -1, "segments", "the model has no segments");
  if (!root_rest_m.allFinite())
    throw ModelError(-1, -1, "root_position", "the root position is not finite");

  // Names: segments unique, points unique across the whole model.
  std::map<std::string, int> seg_index;
  std::map<std::string, std::pair<int, int>> point_owner;  // name -> (segment, point)
  int root = -1;
  for (int s = 0; s < static_cast<int>(specs.size()); ++s) {
    const SegmentSpec& spec = specs[s];
    if (spec.name.empty()) throw ModelError(s, -1, "name", "a segment has an empty name");
    if (!seg_index.emplace(spec.name, s).second)
      throw ModelError(s, -1, "name", "segment name " + quoted(spec.name) + " is used twice");
    if (spec.parent.empty()) {
      if (root >= 0)
        throw ModelError(s, -1, "parent",
                         "two root segments (" + quoted(specs[root].name) + " and " +
                             quoted(spec.name) + "): exactly one segment has no parent");
      root = s;
    }
    if (spec.base.empty())
      throw ModelError(s, -1, "base", "segment " + quoted(spec.name) + " has no base joint");
    if (spec.points.empty())
      throw ModelError(s, -1, "points", "segment " + quoted(spec.name) + " has no points");
    bool extent = false;
    for (int p = 0; p < static_cast<int>(spec.points.size()); ++p) {
      const PointSpec& ps = spec.points[p];
      if (ps.name.empty()) throw ModelError(s, p, "name", "a point has an empty name");
      if (!ps.p_local_m.allFinite())
        throw ModelError(s, p, "position", "point " + quoted(ps.name) + " is not finite");
      if (ps.name == spec.base)
        throw ModelError(
            s, p, "name",
            "point " + quoted(ps.name) +
                " repeats the segment's own base (the base is the origin, do not list it)");
      if (!point_owner.emplace(ps.name, std::make_pair(s, p)).second)
        throw ModelError(s, p, "name", "point name " + quoted(ps.name) + " is used twice");
      extent = extent || ps.p_local_m.norm() > kMinExtentM;
    }
    if (!extent)
      throw ModelError(
          s, -1, "points",
          "segment " + quoted(spec.name) + " has no extent: all its points sit on its base");
  }
  if (root < 0)
    throw ModelError(-1, -1, "segments", "no root segment: exactly one segment has no parent");

  // Parents and bases: each base is a non-marker point of the parent, used once.
  std::set<std::string> used_bases;
  std::map<int, std::vector<int>> children;
  for (int s = 0; s < static_cast<int>(specs.size()); ++s) {
    const SegmentSpec& spec = specs[s];
    if (s == root) {
      if (point_owner.count(spec.base))
        throw ModelError(s, -1, "base", "root base " + quoted(spec.base) + " is also a point name");
      continue;
    }
    auto parent = seg_index.find(spec.parent);
    if (parent == seg_index.end())
      throw ModelError(s, -1, "parent", "unknown parent segment " + quoted(spec.parent));
    auto owner = point_owner.find(spec.base);
    if (owner == point_owner.end() || owner->second.first != parent->second)
      throw ModelError(s, -1, "base",
                       "base " + quoted(spec.base) + " is not a point of parent segment " +
                           quoted(spec.parent) + ": list it in the parent's points");
    if (specs[owner->second.first].points[owner->second.second].marker)
      throw ModelError(s, -1, "base", "base " + quoted(spec.base) + " is a marker, not a joint");
    if (!used_bases.insert(spec.base).second)
      throw ModelError(s, -1, "base",
                       "joint " + quoted(spec.base) +
                           " is the base of two segments: a joint links exactly two segments");
    children[parent->second].push_back(s);
  }

  // Topological order from the root; anything not reached sits on a cycle.
  std::vector<int> order{root};
  for (std::size_t i = 0; i < order.size(); ++i)
    for (int c : children[order[i]]) order.push_back(c);
  if (order.size() != specs.size()) {
    std::set<int> reached(order.begin(), order.end());
    for (int s = 0; s < static_cast<int>(specs.size()); ++s)
      if (!reached.count(s))
        throw ModelError(
            s, -1, "parent",
            "segment " + quoted(specs[s].name) + " is not connected to the root (parent cycle)");
  }

  Model model;
  model.name = name;
  model.root_rest_m = root_rest_m;
  std::vector<int> new_index(specs.size());
  for (int i = 0; i < static_cast<int>(order.size()); ++i) new_index[order[i]] = i;
  std::map<std::string, int> base_to_child;  // joint name -> child segment (new index)
  for (int i = 1; i < static_cast<int>(order.size()); ++i) base_to_child[specs[order[i]].base] = i;

  for (int i = 0; i < static_cast<int>(order.size()); ++i) {
    const SegmentSpec& spec = specs[order[i]];
    Segment seg;
    seg.name = spec.name;
    seg.parent = i == 0 ? -1 : new_index[seg_index[spec.parent]];
    seg.first_point = static_cast<int>(model.points.size());
    seg.base_point = seg.first_point;
    model.points.push_back(Point{spec.base, i, PointKind::base, Eigen::Vector3d::Zero(), -1});
    for (const PointSpec& ps : spec.points) {
      Point p{ps.name, i, ps.marker ? PointKind::marker : PointKind::end_site, ps.p_local_m, -1};
      if (auto c = base_to_child.find(ps.name); c != base_to_child.end()) {
        p.kind = PointKind::joint;
        p.child_segment = c->second;
      }
      model.points.push_back(p);
    }
    seg.point_count = static_cast<int>(model.points.size()) - seg.first_point;
    model.segments.push_back(seg);
  }
  // Children lists, parent points, joints.
  model.joints.push_back(Joint{specs[root].base, model.segments[0].base_point});
  for (int i = 0; i < static_cast<int>(model.segments.size()); ++i) {
    Segment& seg = model.segments[i];
    seg.first_child = static_cast<int>(model.child_ids.size());
    for (int c : children[order[i]]) model.child_ids.push_back(new_index[c]);
    seg.child_count = static_cast<int>(model.child_ids.size()) - seg.first_child;
  }
  for (int p = 0; p < static_cast<int>(model.points.size()); ++p) {
    const Point& pt = model.points[p];
    if (pt.kind != PointKind::joint) continue;
    model.segments[pt.child_segment].parent_point = p;
    model.joints.push_back(Joint{pt.name, model.segments[pt.child_segment].base_point});
  }
  return model;
}

}  // namespace fabrik
