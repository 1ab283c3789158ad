#include "derive_anatomy.hpp"

#include <cmath>
#include <cstdio>
#include <set>

#include "anatomy_names.hpp"

namespace fabrik::calib {

namespace {

// A segment shorter than this has no long axis of its own.
constexpr double kMinLongAxis_m = 0.01;
// A marker pair within 45 deg of the long axis is not a mediolateral line
// (cos 45 deg).
constexpr double kPairAxisMaxCos = 0.7071067811865476;
// A reference within 30 deg of the long axis cannot fix the rotation about it
// (cos 30 deg).
constexpr double kReferenceMaxCos = 0.8660254037844387;

std::string side_suffix(BodySide side) {
  return side == BodySide::right ? "_r" : side == BodySide::left ? "_l" : "";
}

class Deriver {
 public:
  Deriver(const CalibTemplate& t, std::span<const Eigen::Vector3d> points,
          std::span<const Eigen::Vector3d> means,
          std::span<const std::optional<Eigen::Matrix3d>> given)
      : t_(t), points_(points), means_(means), given_(given) {}

  DerivedAnatomy run() {
    const std::size_t n = t_.segments.size();
    out_.frames.assign(n, std::nullopt);
    if (!t_.coordinates.is_null()) return std::move(out_);
    std::vector<std::string> names;
    for (const SegmentDef& s : t_.segments) names.push_back(s.name);
    side_ = sides_of(names);
    children_.assign(n, {});
    for (std::size_t s = 1; s < n; ++s) children_[t_.segments[s].parent].push_back(static_cast<int>(s));
    for (const std::string& name : names) part_.push_back(body_part(name));
    frame_.assign(n, Eigen::Matrix3d::Identity());
    how_.assign(n, "");
    if (!root_frame()) return fail();
    for (std::size_t s = 1; s < n; ++s) segment_frame(static_cast<int>(s));
    coordinates();
    return std::move(out_);
  }

 private:
  Eigen::Vector3d position(const std::string& name) const {
    if (const int p = t_.find_point(name); p >= 0) return points_[p];
    return means_[t_.find_marker(name)];
  }
  Eigen::Vector3d base(int s) const { return position(t_.segments[s].base); }

  bool limb(int s) const { return is_limb(part_[s]) || side_[s] != BodySide::none; }
  bool recognised_axial(int s) const {
    return part_[s] == BodyPart::trunk || part_[s] == BodyPart::head;
  }

  // Where segment s ends, and the point's template index when it is one
  // point (for its marker pair); nullopt when it has no distal point.
  std::optional<Eigen::Vector3d> distal(int s, int& single_point, std::string& what) const {
    single_point = -1;
    const std::vector<int>& kids = children_[s];
    std::vector<int> axial;
    for (int c : kids)
      if (!limb(c)) axial.push_back(c);
    if (kids.size() == 1 || axial.size() == 1) {
      const int c = kids.size() == 1 ? kids[0] : axial[0];
      single_point = t_.find_point(t_.segments[c].base);
      what = t_.segments[c].base;
      return base(c);
    }
    if (!kids.empty()) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int c : kids) sum += base(c);
      what = "the mean of its " + std::to_string(kids.size()) + " joints";
      return sum / static_cast<double>(kids.size());
    }
    // A leaf: its end sites, else its markers.
    std::vector<int> ends;
    for (std::size_t p = 0; p < t_.points.size(); ++p)
      if (t_.points[p].segment == s && t_.points[p].name != t_.segments[s].base)
        ends.push_back(static_cast<int>(p));
    if (!ends.empty()) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int p : ends) sum += points_[p];
      if (ends.size() == 1) single_point = ends[0];
      what = ends.size() == 1 ? t_.points[ends[0]].name : "the mean of its end sites";
      return sum / static_cast<double>(ends.size());
    }
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int count = 0;
    for (std::size_t m = 0; m < t_.markers.size(); ++m)
      if (t_.markers[m].segment == s && means_[m].allFinite()) {
        sum += means_[m];
        ++count;
      }
    if (count == 0) return std::nullopt;
    what = "its markers' centroid";
    return sum / count;
  }

  // The root: y up, z right, x = y cross z.
  bool root_frame() {
    if (given_[0]) {
      frame_[0] = *given_[0];
      return true;
    }
    Eigen::Vector3d up = Eigen::Vector3d::Zero();
    std::string from;
    for (int c : children_[0]) {
      int single = -1;
      std::string what;
      const std::optional<Eigen::Vector3d> d = distal(c, single, what);
      if (!d || (*d - base(c)).norm() < kMinLongAxis_m) continue;
      const Eigen::Vector3d along = (*d - base(c)).normalized();
      if (limb(c)) {
        up -= along;  // a limb's proximal direction
      } else if (recognised_axial(c)) {
        up += along;
      } else {
        continue;
      }
      from += (from.empty() ? "" : ", ") + t_.segments[c].name;
    }
    if (up.norm() < 1e-6) {
      why_ = "no child of the root segment '" + t_.segments[0].name +
             "' is a limb (a side in its name, or thigh, shank, humerus, ...) or a trunk or head, "
             "so the body's up is unknown";
      return false;
    }
    up.normalize();
    // Right: every mirrored pair of markers and points, right minus left.
    std::vector<std::string> names;
    std::vector<Eigen::Vector3d> where;
    for (std::size_t m = 0; m < t_.markers.size(); ++m)
      if (means_[m].allFinite()) {
        names.push_back(t_.markers[m].name);
        where.push_back(means_[m]);
      }
    for (std::size_t p = 0; p < t_.points.size(); ++p) {
      names.push_back(t_.points[p].name);
      where.push_back(points_[p]);
    }
    Eigen::Vector3d right = Eigen::Vector3d::Zero();
    const auto pairs = mirrored_pairs(names);
    for (const auto& [r, l] : pairs) right += where[r] - where[l];
    right -= up * up.dot(right);
    if (pairs.empty() || right.norm() < kMinLongAxis_m) {
      why_ = "no left/right pairs of markers or points (names such as RASI/LASI, R.ASIS/L.ASIS, "
             "r_hip/l_hip), so the body's right is unknown";
      return false;
    }
    const Eigen::Vector3d z = right.normalized();
    frame_[0] << up.cross(z), up, z;
    out_.frames[0] = frame_[0];
    how_[0] = "y up (from " + from + "), z right (from " + std::to_string(pairs.size()) +
              " left/right pairs)";
    return true;
  }

  // A joint with ranges was written against the lab's axes at the static
  // posture: its frames keep them.
  bool ranges_need_rest_frame(int s) const {
    auto ranged = [&](int seg) {
      const nlohmann::json& j = t_.segments[seg].joint;
      return j.is_object() && j.contains("range_deg");
    };
    if (ranged(s)) return true;
    for (int c : children_[s])
      if (ranged(c)) return true;
    return false;
  }

  void take_parent_frame(int s, const std::string& why) {
    const int parent = t_.segments[s].parent;
    frame_[s] = frame_[parent];
    out_.frames[s] = frame_[s];
    how_[s] = t_.segments[parent].name + "'s (" + why + ")";
  }

  void segment_frame(int s) {
    const SegmentDef& sd = t_.segments[s];
    const int parent = sd.parent;
    if (given_[s]) {
      frame_[s] = *given_[s];
      return;
    }
    if (ranges_need_rest_frame(s)) {
      how_[s] = "the lab's axes at the static posture: kept, since a joint range here was written "
                "for them";
      return;
    }
    if (takes_parent_frame(part_[s])) return take_parent_frame(s, "a foot's frame is the shank's at neutral, as ISB's calcaneus");
    int single = -1;
    std::string what;
    const std::optional<Eigen::Vector3d> d = distal(s, single, what);
    if (!d || (*d - base(s)).norm() < kMinLongAxis_m)
      return take_parent_frame(s, "it has no distal point 1 cm or more from its base");
    const Eigen::Vector3d along = (*d - base(s)).normalized();
    const Eigen::Vector3d up = frame_[0].col(1);
    // A leaf lying flat below the root whose parent stands upright: a foot by its shape.
    if (part_[s] == BodyPart::unknown && children_[s].empty() && std::abs(along.dot(up)) < kPairAxisMaxCos &&
        (base(s) - base(0)).dot(up) < 0 && std::abs(frame_[parent].col(1).dot(up)) > kPairAxisMaxCos)
      return take_parent_frame(s, "a leaf lying flat below the root: a foot by its shape");
    const bool proximal = limb(s) || along.dot(up) < 0;
    const Eigen::Vector3d y = proximal ? Eigen::Vector3d(-along) : along;
    std::string y_how = proximal ? "y " + what + " -> " + sd.base : "y " + sd.base + " -> " + what;
    // z: the parent's, or its x where the parent's z lies along y (an arm held out sideways).
    Eigen::Vector3d z;
    std::string z_how;
    const Eigen::Vector3d pz = frame_[parent].col(2);
    if (std::abs(pz.dot(y)) < kReferenceMaxCos) {
      z = (pz - y * y.dot(pz)).normalized();
      z_how = "z from " + t_.segments[parent].name + "'s z";
    } else {
      const Eigen::Vector3d px = frame_[parent].col(0);
      z = (px - y * y.dot(px)).normalized().cross(y);
      z_how = "z from " + t_.segments[parent].name + "'s x (its z lies along y)";
    }
    // The two markers whose midpoint is the distal joint lie across the limb.
    if (single >= 0 && t_.points[single].rule == PointRule::midpoint &&
        t_.points[single].refs.size() == 2) {
      const PointRef& a = t_.points[single].refs[0];
      const PointRef& b = t_.points[single].refs[1];
      Eigen::Vector3d pair = Eigen::Vector3d::Zero();
      for (const std::string& n : b.names) pair += position(n) / static_cast<double>(b.names.size());
      for (const std::string& n : a.names) pair -= position(n) / static_cast<double>(a.names.size());
      if (pair.norm() >= kMinLongAxis_m && std::abs(pair.normalized().dot(y)) < kPairAxisMaxCos) {
        const bool flip = pair.dot(z) < 0;
        if (flip) pair = -pair;
        z = (pair - y * y.dot(pair)).normalized();
        z_how = "z " + (flip ? b : a).names.front() + " -> " + (flip ? a : b).names.front();
      }
    }
    frame_[s] << y.cross(z), y, z;
    out_.frames[s] = frame_[s];
    how_[s] = y_how + ", " + z_how;
  }

  // The angles a joint type lets turn, as (index, letter): z, x, y.
  static std::vector<int> turning_angles(const nlohmann::json& joint) {
    const std::string type = joint.is_object() && joint.contains("type") && joint["type"].is_string()
                                 ? joint["type"].get<std::string>()
                                 : "free";
    if (type == "fixed") return {};
    if (type == "hinge") return {0};
    if (type == "universal") return {0, 1};
    return {0, 1, 2};
  }

  void add(const std::string& name, nlohmann::ordered_json entry, std::string& line) {
    used_.insert(name);
    out_.coordinates[name] = std::move(entry);
    line += " " + name;
  }

  void coordinates() {
    out_.coordinates = nlohmann::ordered_json::object();
    const char* letters[3] = {"z", "x", "y"};
    const SegmentDef& root = t_.segments[0];
    std::vector<std::string> lines(t_.segments.size());
    {
      const bool pelvis = part_[0] == BodyPart::pelvis;
      const std::string stem = pelvis ? "pelvis" : root.name;
      const char* words[3] = {"_tilt", "_list", "_rotation"};
      for (int k = 0; k < 3; ++k)
        add(stem + words[k], {{"segment", root.name}, {"axis", letters[k]}, {"relative_to", "world"}},
            lines[0]);
      for (const char* axis : {"x", "y", "z"})
        add(stem + "_t" + axis, {{"point", root.base}, {"axis", axis}}, lines[0]);
    }
    for (std::size_t s = 1; s < t_.segments.size(); ++s) {
      const SegmentDef& sd = t_.segments[s];
      const JointCoordinateNames os = opensim_names(part_[s]);
      const std::string opensim[3] = {os.z, os.x, os.y};
      const bool is_limb = limb(static_cast<int>(s));
      const char* words[3] = {is_limb ? "_flexion" : "_extension", is_limb ? "_adduction" : "_bending",
                              "_rotation"};
      // OpenSim's arm angles are the humerus relative to the thorax.
      std::string relative_to;
      if (part_[s] == BodyPart::upper_arm && part_[sd.parent] == BodyPart::shoulder_girdle &&
          t_.segments[sd.parent].parent >= 0)
        relative_to = t_.segments[t_.segments[sd.parent].parent].name;
      for (int k : turning_angles(sd.joint)) {
        std::string name = opensim[k].empty() ? "" : opensim[k] + side_suffix(side_[s]);
        const bool named = !name.empty() && !used_.count(name);
        if (!named) name = sd.name + words[k];
        nlohmann::ordered_json e = {{"segment", sd.name}, {"axis", letters[k]}};
        if (named && !relative_to.empty()) e["relative_to"] = relative_to;
        // Adduction and internal rotation positive on both sides, as OpenSim's.
        if (side_[s] == BodySide::left && k > 0) e["sign"] = -1;
        add(name, e, lines[s]);
      }
    }
    out_.report.push_back("angles derived (the template names no coordinates; docs/calibration.md, "
                          "\"Angles for any template\"); joints without a \"joint\" stay free:");
    for (std::size_t s = 0; s < t_.segments.size(); ++s) {
      std::string line = "  " + t_.segments[s].name + ": ";
      line += "frame " + (how_[s].empty() ? std::string("from the template") : how_[s]);
      if (!lines[s].empty()) line += "; coordinates" + lines[s];
      out_.report.push_back(line);
    }
  }

  DerivedAnatomy fail() {
    out_.failed = true;
    out_.frames.assign(t_.segments.size(), std::nullopt);
    out_.report.push_back(
        "no angles: the template names no coordinates and they cannot be derived: " + why_ +
        ". Fix: give the root segment '" + t_.segments[0].name +
        "' a frame, e.g. \"frame\": [{\"axis\": \"z\", \"from\": \"LASI\", \"to\": \"RASI\"}, "
        "{\"axis\": \"y\", \"from\": [\"r_knee\", \"l_knee\"], \"to\": [\"RASI\", \"LASI\"]}] "
        "(z: a left marker to its right partner; y: from below to above), and calibrate again");
    return std::move(out_);
  }

  const CalibTemplate& t_;
  std::span<const Eigen::Vector3d> points_, means_;
  std::span<const std::optional<Eigen::Matrix3d>> given_;
  DerivedAnatomy out_;
  std::vector<BodySide> side_;
  std::vector<BodyPart> part_;
  std::vector<std::vector<int>> children_;
  std::vector<Eigen::Matrix3d> frame_;  // per segment: given, derived, or the lab's axes
  std::vector<std::string> how_;        // per segment: how its frame was derived
  std::set<std::string> used_;          // coordinate names taken
  std::string why_;                     // why the root frame could not be derived
};

}  // namespace

DerivedAnatomy derive_anatomy(const CalibTemplate& tmpl, std::span<const Eigen::Vector3d> point_world_m,
                              std::span<const Eigen::Vector3d> marker_mean_m,
                              std::span<const std::optional<Eigen::Matrix3d>> given_frames) {
  return Deriver(tmpl, point_world_m, marker_mean_m, given_frames).run();
}

}  // namespace fabrik::calib
