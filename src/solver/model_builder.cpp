#include "model_builder.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

namespace fabrik {

// Model's constructor is private: only the builder assembles one.
class ModelAssembly {
 public:
  template <class... Args>
  static Model make(Args&&... args) {
    return Model(std::forward<Args>(args)...);
  }
};

namespace {
constexpr double kMinExtentM = 1e-9;
constexpr double kMinBoneM = 1e-3;
constexpr double kPi = 3.141592653589793;
constexpr double kGimbalMarginRad = 0.01;

std::string quoted(const std::string& s) {
  return "'" + s + "'";
}

// The anatomical frame as a unit quaternion; the matrix must be a rotation.
Eigen::Quaterniond anatomical_frame(int spec, const Eigen::Matrix3d& axes) {
  const double orthogonality = (axes.transpose() * axes - Eigen::Matrix3d::Identity()).norm();
  if (!axes.allFinite() || orthogonality > 1e-6 || axes.determinant() < 0.0)
    throw ModelError(spec, -1, "frame",
                     "the anatomical frame is not a right-handed set of unit axes at right "
                     "angles (x cross y must be z)");
  return Eigen::Quaterniond(axes).normalized();
}

// A joint's ranges, checked, with held angles set to the rest angles (the
// anatomical frames' relative rotation at rest, where all segment frames
// are the world's).
JointLimits joint_limits(int spec_index, const SegmentSpec& spec,
                         const std::vector<Segment>& segments, int s) {
  JointLimits j;
  const JointSpec& js = spec.joint;
  if (s == 0) {
    if (js.type != JointType::free)
      throw ModelError(spec_index, -1, "joint",
                       "the root segment " + quoted(spec.name) +
                           " has no parent joint to limit: give its joint no type");
    return j;
  }
  j.type = js.type;
  const Eigen::Matrix3d rest =
      segments[segments[s].parent].q_anatomical.toRotationMatrix().transpose() *
      segments[s].q_anatomical.toRotationMatrix();
  const double b = std::asin(std::clamp(rest(2, 1), -1.0, 1.0));
  j.rest_rad = {std::atan2(-rest(0, 1), rest(1, 1)), b, std::atan2(-rest(2, 0), rest(2, 2))};
  // Which angles move: z, x, y.
  bool moves[3] = {true, true, true};
  switch (js.type) {
    case JointType::free:
      return j;
    case JointType::ball:
      break;
    case JointType::universal:
      moves[2] = false;
      break;
    case JointType::hinge:
      moves[1] = moves[2] = false;
      break;
    case JointType::fixed:
      moves[0] = moves[1] = moves[2] = false;
      break;
  }
  static constexpr const char* kAxis[3] = {"z", "x", "y"};
  for (int k = 0; k < 3; ++k) {
    if (!moves[k]) {
      j.min_rad[k] = j.max_rad[k] = j.rest_rad[k];
      continue;
    }
    const double bound = k == 1 ? kPi / 2 : kPi;
    const double lo = js.min_rad[k], hi = js.max_rad[k];
    if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi || lo < -bound - 1e-12 ||
        hi > bound + 1e-12)
      throw ModelError(spec_index, -1, "joint",
                       std::string("the range of the joint's ") + kAxis[k] + " angle of segment " +
                           quoted(spec.name) + " must be [min, max] with min <= max within [-" +
                           (k == 1 ? "90, 90" : "180, 180") + "] degrees");
    // a_x stops short of +-90 degrees, where the Cardan decomposition is
    // singular (a_z and a_y become one rotation) and no range can be checked.
    const double reach = k == 1 ? bound - kGimbalMarginRad : bound;
    j.min_rad[k] = std::clamp(lo, -reach, reach);
    j.max_rad[k] = std::clamp(hi, -reach, reach);
  }
  return j;
}
}  // namespace

Model build_model(const std::string& name, const std::vector<SegmentSpec>& specs,
                  const Eigen::Vector3d& root_rest_m,
                  const std::vector<CoordinateSpec>& coordinates, const LabAxes& lab_axes) {
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

  std::vector<int> new_index(specs.size());
  for (int i = 0; i < static_cast<int>(order.size()); ++i) new_index[order[i]] = i;
  std::map<std::string, int> base_to_child;  // joint name -> child segment (new index)
  for (int i = 1; i < static_cast<int>(order.size()); ++i) base_to_child[specs[order[i]].base] = i;

  std::vector<Segment> segments;
  std::vector<Point> points;
  std::vector<int> child_ids;
  std::vector<Joint> joints;
  for (int i = 0; i < static_cast<int>(order.size()); ++i) {
    const SegmentSpec& spec = specs[order[i]];
    Segment seg;
    seg.name = spec.name;
    seg.parent = i == 0 ? -1 : new_index[seg_index[spec.parent]];
    seg.first_point = static_cast<int>(points.size());
    seg.base_point = seg.first_point;
    seg.q_anatomical = anatomical_frame(order[i], spec.anatomical);
    points.push_back(Point{spec.base, i, PointKind::base, Eigen::Vector3d::Zero(), -1});
    for (std::size_t k = 0; k < spec.points.size(); ++k) {
      const PointSpec& ps = spec.points[k];
      Point p{ps.name, i, ps.marker ? PointKind::marker : PointKind::end_site, ps.p_local_m, -1};
      if (auto c = base_to_child.find(ps.name); c != base_to_child.end()) {
        p.kind = PointKind::joint;
        p.child_segment = c->second;
        // FABRIK orients a segment along base -> joint: a joint on the base
        // leaves it no direction (it would track far off and say converged).
        if (ps.p_local_m.norm() < kMinBoneM)
          throw ModelError(order[i], static_cast<int>(k), "position",
                           "joint " + quoted(ps.name) + " of segment " + quoted(spec.name) +
                               " sits on the segment's base " + quoted(spec.base) + " (" +
                               std::to_string(ps.p_local_m.norm() * 1e3) +
                               " mm away: a zero-length bone); give it its position relative "
                               "to the base, at least 1 mm away");
      }
      points.push_back(p);
    }
    seg.point_count = static_cast<int>(points.size()) - seg.first_point;
    segments.push_back(seg);
  }
  // Children lists, parent points, joints.
  joints.push_back(Joint{specs[root].base, segments[0].base_point});
  for (int i = 0; i < static_cast<int>(segments.size()); ++i) {
    Segment& seg = segments[i];
    seg.first_child = static_cast<int>(child_ids.size());
    for (int c : children[order[i]]) child_ids.push_back(new_index[c]);
    seg.child_count = static_cast<int>(child_ids.size()) - seg.first_child;
  }
  for (int p = 0; p < static_cast<int>(points.size()); ++p) {
    const Point& pt = points[p];
    if (pt.kind != PointKind::joint) continue;
    segments[pt.child_segment].parent_point = p;
    joints.push_back(Joint{pt.name, segments[pt.child_segment].base_point});
  }
  // Joint limits need both anatomical frames: set them once all are known.
  for (int i = 0; i < static_cast<int>(segments.size()); ++i)
    segments[i].joint = joint_limits(order[i], specs[order[i]], segments, i);

  std::vector<Coordinate> coords;
  std::set<std::string> coordinate_names;
  auto find_segment = [&](const std::string& n) {
    for (int i = 0; i < static_cast<int>(segments.size()); ++i)
      if (segments[i].name == n) return i;
    return -1;
  };
  for (const CoordinateSpec& cs : coordinates) {
    const std::string field = "coordinates/" + cs.name;
    auto fail = [&](const std::string& what) { throw ModelError(-1, -1, field, what); };
    if (cs.name.empty()) fail("a coordinate has an empty name");
    if (!coordinate_names.insert(cs.name).second)
      fail("coordinate name " + quoted(cs.name) + " is used twice");
    if (cs.axis < 0 || cs.axis > 2) fail("coordinate axis must be x, y or z");
    if (!std::isfinite(cs.sign) || !std::isfinite(cs.offset) || cs.sign == 0.0)
      fail("coordinate " + quoted(cs.name) + " needs a finite, non-zero sign and a finite offset");
    Coordinate c;
    c.name = cs.name;
    c.kind = cs.kind;
    c.sign = cs.sign;
    c.offset = cs.offset;
    if (cs.kind == CoordinateKind::rotation) {
      c.segment = find_segment(cs.segment);
      if (c.segment < 0) fail("coordinate " + quoted(cs.name) + ": unknown segment " + quoted(cs.segment));
      if (!cs.relative_to.empty()) {
        c.relative_to = find_segment(cs.relative_to);
        if (c.relative_to < 0)
          fail("coordinate " + quoted(cs.name) + ": unknown segment " + quoted(cs.relative_to));
      }
      // Cardan order z, x, y: the axis letter names the angle.
      static constexpr int kAngleOfAxis[3] = {1, 2, 0};
      c.angle = kAngleOfAxis[cs.axis];
    } else {
      int index = -1;
      for (int p = 0; p < static_cast<int>(points.size()); ++p)
        if (points[p].name == cs.point) index = p;
      if (index < 0)
        fail("coordinate " + quoted(cs.name) + ": unknown point " + quoted(cs.point));
      c.point = index;
      c.axis = cs.axis;
    }
    coords.push_back(c);
  }
  const double up_norm = lab_axes.up_lab.norm(), forward_norm = lab_axes.forward_lab.norm();
  if (!(std::abs(up_norm - 1.0) < 1e-9 && std::abs(forward_norm - 1.0) < 1e-9 &&
        std::abs(lab_axes.up_lab.dot(lab_axes.forward_lab)) < 1e-9))
    throw ModelError(-1, -1, "lab_axes", "the lab's up and forward axes must be unit axes at right angles");
  return ModelAssembly::make(name, std::move(segments), std::move(points), std::move(child_ids),
                             std::move(joints), std::move(coords), root_rest_m, lab_axes);
}

Model without_joint_limits(const Model& model) {
  std::vector<Segment> segments = model.segments;
  for (Segment& s : segments) s.joint = JointLimits{};
  return ModelAssembly::make(model.name, std::move(segments), model.points, model.child_ids,
                             model.joints, model.coordinates, model.root_rest_m, model.lab_axes);
}

}  // namespace fabrik
