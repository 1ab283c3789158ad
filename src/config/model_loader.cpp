#include "model_loader.hpp"

#include <Eigen/SVD>
#include <string_view>
#include <unordered_map>

#include "json_reader.hpp"
#include "lab_axes_json.hpp"
#include "solver/model_builder.hpp"
#include "solver/units.hpp"

namespace fabrik {

double metres_per_unit(const JsonReader& units) {
  const std::string u = units.as_string();
  if (u == "m") return 1.0;
  if (u == "mm") return 1e-3;
  units.fail("unknown unit '" + u + "'", "use \"m\" or \"mm\"");
}

namespace {

// {"x": [..], "y": [..], "z": [..]}: the anatomical axes in the rest frame.
// Two axes are enough (the third completes a right-handed frame); a third,
// if given, must agree. Columns of the result are x, y, z.
Eigen::Matrix3d read_frame(const JsonReader& f) {
  f.expect_object();
  f.only_keys({"x", "y", "z", "description"});
  const char* names[3] = {"x", "y", "z"};
  Eigen::Vector3d axis[3];
  bool given[3];
  int n = 0;
  for (int k = 0; k < 3; ++k) {
    given[k] = f.has(names[k]);
    if (!given[k]) continue;
    axis[k] = f.at(names[k]).as_vec3();
    if (axis[k].norm() < 1e-9) f.at(names[k]).fail("the axis has no direction", "give a non-zero vector");
    axis[k].normalize();
    ++n;
  }
  if (n < 2) f.fail("a frame needs at least two of its axes", "give \"x\", \"y\" and/or \"z\" as unit vectors");
  // Complete a missing axis: x = y cross z, y = z cross x, z = x cross y.
  for (int k = 0; k < 3; ++k)
    if (!given[k]) axis[k] = axis[(k + 1) % 3].cross(axis[(k + 2) % 3]);
  Eigen::Matrix3d m;
  m << axis[0], axis[1], axis[2];
  if ((m.transpose() * m - Eigen::Matrix3d::Identity()).norm() > 1e-3 || m.determinant() < 0)
    f.fail("the axes are not at right angles or not right-handed (x cross y must be z)",
           "give orthogonal unit axes");
  // Rounding in the file: the nearest rotation (polar decomposition).
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.matrixV().transpose();
}

// {"type": "hinge", "range_deg": {"z": [min, max]}}: see JointLimits.
JointSpec read_joint(const JsonReader& j) {
  j.expect_object();
  j.only_keys({"type", "range_deg", "description"});
  JointSpec spec;
  spec.type = read_choice<JointType>(j.at("type"), "joint type",
                                     {{"free", JointType::free},
                                      {"ball", JointType::ball},
                                      {"universal", JointType::universal},
                                      {"hinge", JointType::hinge},
                                      {"fixed", JointType::fixed}});
  if (!j.has("range_deg")) return spec;
  const JsonReader r = j.at("range_deg");
  if (spec.type == JointType::free)  // its angles are never limited: a range would be ignored
    r.fail("a free joint is not limited (and a root's joint is free)",
           "give the joint the type whose angles the ranges limit (ball, universal or hinge), "
           "or remove range_deg");
  r.expect_object();
  r.only_keys({"z", "x", "y"});
  const char* names[3] = {"z", "x", "y"};
  // Which angles the type lets move (z, x, y): a range for a held angle is a mistake.
  const bool moves[5][3] = {{true, true, true}, {true, true, true}, {true, true, false},
                            {true, false, false}, {false, false, false}};
  for (int k = 0; k < 3; ++k) {
    if (!r.has(names[k])) continue;
    const JsonReader range = r.at(names[k]);
    if (!moves[static_cast<int>(spec.type)][k])
      range.fail(std::string("a ") + j.at("type").as_string() + " joint holds its " + names[k] +
                     " angle at rest",
                 std::string("remove this range, or choose a joint type that turns about ") + names[k]);
    range.expect_array();
    if (range.value().size() != 2)
      range.fail("a range is [min, max] in degrees", "write e.g. [-10, 120]");
    const double bound = k == 1 ? 90.0 : 180.0;
    const double lo = range.at(std::size_t{0}).as_number(-bound, bound);
    const double hi = range.at(std::size_t{1}).as_number(-bound, bound);
    if (lo > hi) range.fail("min is larger than max", "write [min, max]");
    spec.min_rad[k] = lo * kRadPerDeg;
    spec.max_rad[k] = hi * kRadPerDeg;
  }
  return spec;
}

int read_axis_letter(const JsonReader& a) {
  return read_choice<int>(a, "axis", {{"x", 0}, {"y", 1}, {"z", 2}});
}

// "coordinates": {NAME: {"segment": S, "relative_to": R|"world", "axis": "z",
// "sign": 1, "offset_deg": 0} or {"point": P, "axis": "x", "sign": 1, "offset": 0}}.
std::vector<CoordinateSpec> read_coordinates(const JsonReader& c,
                                             const std::vector<SegmentSpec>& specs, double scale) {
  c.expect_object();
  std::vector<CoordinateSpec> out;
  for (auto it = c.value().begin(); it != c.value().end(); ++it) {
    const JsonReader e = c.at(it.key());
    e.expect_object();
    CoordinateSpec cs;
    cs.name = it.key();
    cs.sign = e.get("sign", 1.0, -1e6, 1e6);
    if (cs.sign == 0.0) e.at("sign").fail("the sign is zero", "use 1 or -1");
    cs.axis = read_axis_letter(e.at("axis"));
    if (e.has("point")) {
      e.only_keys({"point", "axis", "sign", "offset", "description"});
      cs.kind = CoordinateKind::translation;
      cs.point = e.at("point").as_string();
      cs.offset = e.get("offset", 0.0, -1e6, 1e6) * scale;
    } else {
      e.only_keys({"segment", "relative_to", "axis", "sign", "offset_deg", "description"});
      cs.kind = CoordinateKind::rotation;
      cs.segment = e.at("segment").as_string();
      const SegmentSpec* seg = nullptr;
      for (const SegmentSpec& s : specs)
        if (s.name == cs.segment) seg = &s;
      if (!seg)
        e.at("segment").fail("the model has no segment '" + cs.segment + "'",
                             "name one of the model's segments");
      // Default: relative to the parent (the joint's angles), the world for the root.
      cs.relative_to = e.has("relative_to") ? e.at("relative_to").as_string() : seg->parent;
      if (cs.relative_to == "world") cs.relative_to.clear();
      cs.offset = e.get("offset_deg", 0.0, -360.0, 360.0) * kRadPerDeg;
    }
    out.push_back(cs);
  }
  return out;
}

void read_points(const JsonReader& obj, double scale, bool marker, std::vector<PointSpec>& out) {
  obj.expect_object();
  ModelLimits::check_points(obj, out.size() + obj.value().size());
  for (auto it = obj.value().begin(); it != obj.value().end(); ++it) {
    const JsonReader p = obj.at(it.key());
    out.push_back(PointSpec{it.key(), p.as_vec3() * scale, marker});
  }
}
// Segments from the root, by parent name, without building the model: a
// cycle or an unknown parent is left to build_model's own messages.
void check_depth(const JsonReader& segs, const std::vector<SegmentSpec>& specs) {
  std::unordered_map<std::string_view, int> index;
  for (int s = 0; s < static_cast<int>(specs.size()); ++s) index.emplace(specs[s].name, s);
  std::vector<int> depth(specs.size(), 0);  // 0: not known yet, -1: on the path being walked
  std::vector<int> path;
  for (int s = 0; s < static_cast<int>(specs.size()); ++s) {
    path.clear();
    int at = s;
    while (at >= 0 && depth[at] == 0) {
      depth[at] = -1;
      path.push_back(at);
      const auto parent = specs[at].parent.empty() ? index.end() : index.find(specs[at].parent);
      at = parent == index.end() ? -1 : parent->second;
    }
    if (at >= 0 && depth[at] < 0) {  // a parent cycle: build_model names it
      for (int p : path) depth[p] = 1;
      continue;
    }
    int d = at >= 0 ? depth[at] : 0;
    for (auto it = path.rbegin(); it != path.rend(); ++it) depth[*it] = ++d;
    if (!path.empty() && d > ModelLimits::kDepth)  // the root has no "parent" to point at
      ModelLimits::check_depth(segs.at(static_cast<std::size_t>(path.front())).at("parent"),
                               specs[path.front()].name, d);
  }
}

}  // namespace

void ModelLimits::check_segments(const JsonReader& segs) {
  if (segs.value().size() > kSegments)
    segs.at(std::size_t{kSegments})
        .fail("there are " + std::to_string(segs.value().size()) +
                  " segments; fabrikd takes at most " + std::to_string(kSegments),
              "merge segments that do not move relative to each other (a body with hands and a "
              "segmented spine has about 150)");
}

void ModelLimits::check_points(const JsonReader& where, std::size_t n) {
  if (n > kPointsPerSegment)
    where.fail("a segment has " + std::to_string(n) + " points and markers; fabrikd takes at most " +
                   std::to_string(kPointsPerSegment),
               "split the segment, or keep the markers the solve needs (a rigid segment is "
               "tracked from 3 or 4)");
}

void ModelLimits::check_markers(const JsonReader& where, std::size_t n) {
  if (n > kMarkers)
    where.fail("there are more than " + std::to_string(kMarkers) +
                   " markers with these; fabrikd takes at most " + std::to_string(kMarkers),
               "keep the markers the solve needs (3 or 4 per segment)");
}

void ModelLimits::check_depth(const JsonReader& parent, const std::string& segment, int depth) {
  if (depth > kDepth)
    parent.fail("segment '" + segment + "' ends a chain of more than " + std::to_string(kDepth) +
                    " segments from the root (both counted); fabrikd takes at most " +
                    std::to_string(kDepth),
                "attach long chains nearer the root, or merge segments that do not move "
                "relative to each other");
}

Model load_model(const nlohmann::json& doc, const std::string& file) {
  return load_model(JsonReader(doc, file));
}

Model load_model(const JsonReader& root) {
  root.only_keys({"format", "name", "units", "root_position", "segments", "coordinates",
                  "lab_axes", "description"});
  if (root.has("format") && root.at("format").as_string() != "fabrikd-model/1")
    root.at("format").fail("unsupported format '" + root.at("format").as_string() + "'",
                           "use \"fabrikd-model/1\"");
  const std::string name = root.get("name", std::string("model"));
  const double scale = metres_per_unit(root.at("units"));
  const Eigen::Vector3d root_m = root.has("root_position")
                                     ? Eigen::Vector3d(root.at("root_position").as_vec3() * scale)
                                     : Eigen::Vector3d::Zero();
  const JsonReader segs = root.at("segments");
  segs.expect_array();
  ModelLimits::check_segments(segs);
  std::vector<SegmentSpec> specs;
  std::size_t markers = 0;
  for (std::size_t i = 0; i < segs.value().size(); ++i) {
    const JsonReader s = segs.at(i);
    s.only_keys({"name", "parent", "base", "points", "markers", "frame", "joint", "description"});
    SegmentSpec spec;
    spec.name = s.at("name").as_string();
    spec.parent =
        s.has("parent") && !s.at("parent").value().is_null() ? s.at("parent").as_string() : "";
    spec.base = s.at("base").as_string();
    if (s.has("points")) read_points(s.at("points"), scale, false, spec.points);
    if (s.has("markers")) {
      const std::size_t before = spec.points.size();
      read_points(s.at("markers"), scale, true, spec.points);
      markers += spec.points.size() - before;
      ModelLimits::check_markers(s.at("markers"), markers);
    }
    if (s.has("frame")) spec.anatomical = read_frame(s.at("frame"));
    if (s.has("joint")) spec.joint = read_joint(s.at("joint"));
    specs.push_back(std::move(spec));
  }
  check_depth(segs, specs);
  if (root.has("coordinates") && root.at("coordinates").value().is_object() &&
      root.at("coordinates").value().size() > ModelLimits::kCoordinates)
    root.at("coordinates")
        .fail("the model names " + std::to_string(root.at("coordinates").value().size()) +
                  " coordinates; fabrikd takes at most " +
                  std::to_string(ModelLimits::kCoordinates),
              "name only the angles you report (three per joint at most)");
  const std::vector<CoordinateSpec> coordinates =
      root.has("coordinates") ? read_coordinates(root.at("coordinates"), specs, scale)
                              : std::vector<CoordinateSpec>{};
  LabAxes lab_axes;
  if (root.has("lab_axes"))
    lab_axes = read_whole_lab_axes(root.at("lab_axes"), "with x up, the lab's forward axis is not clear",
                                   "add \"forward\": \"+y\" (or \"+z\", \"-y\", \"-z\")");
  try {
    return build_model(name, specs, root_m, coordinates, lab_axes);
  } catch (const ModelError& e) {
    // Point the message at the field the builder complained about.
    std::string pointer = root.pointer() + "/segments";
    if (e.segment() >= 0) {
      pointer += "/" + std::to_string(e.segment());
      const SegmentSpec& spec = specs[e.segment()];
      if (e.point() >= 0) {
        const PointSpec& ps = spec.points[e.point()];
        pointer += std::string(ps.marker ? "/markers/" : "/points/") + json_pointer_token(ps.name);
      } else {
        pointer += "/" + e.field();
      }
    } else if (e.field().rfind("coordinates/", 0) == 0) {
      pointer = root.pointer() + "/coordinates/" + json_pointer_token(e.field().substr(12));
    } else if (e.field() != "segments") {
      pointer = root.pointer() + "/" + e.field();
    }
    throw ConfigError(root.file(), pointer, e.what(), "see the model format in docs/models.md");
  }
}

Model load_model_file(const std::string& path) {
  return load_model(JsonReader::parse_file(path), path);
}

}  // namespace fabrik
