#include "calib_template.hpp"

#include <functional>
#include <limits>
#include <map>
#include <set>

#include "config/json_reader.hpp"
#include "config/model_loader.hpp"

namespace fabrik::calib {

int CalibTemplate::find_point(const std::string& n) const {
  for (std::size_t i = 0; i < points.size(); ++i)
    if (points[i].name == n) return static_cast<int>(i);
  return -1;
}
int CalibTemplate::find_marker(const std::string& n) const {
  for (std::size_t i = 0; i < markers.size(); ++i)
    if (markers[i].name == n) return static_cast<int>(i);
  return -1;
}
int CalibTemplate::find_segment(const std::string& n) const {
  for (std::size_t i = 0; i < segments.size(); ++i)
    if (segments[i].name == n) return static_cast<int>(i);
  return -1;
}

Eigen::Vector3d hip_centre_in_pelvis_m(HipRegression regression, bool right, double pelvic_width_m,
                                       double pelvic_depth_m) {
  const double side = right ? 1.0 : -1.0;
  switch (regression) {
    case HipRegression::harrington2007: {
      // Harrington, Zavatsky, Lawson, Yuan & Theologis, "Prediction of the hip
      // joint centre in adults, children, and patients with cerebral palsy
      // based on magnetic resonance imaging", J Biomech 40 (2007) 595-602:
      // the equations from pelvic width and depth, in millimetres.
      const double pw_mm = pelvic_width_m * 1e3, pd_mm = pelvic_depth_m * 1e3;
      return Eigen::Vector3d(-0.24 * pd_mm - 9.9, -0.30 * pw_mm - 10.9,
                             side * (0.33 * pw_mm + 7.3)) *
             1e-3;
    }
  }
  return Eigen::Vector3d::Zero();
}

namespace {

PointRef read_ref(const JsonReader& r) {
  PointRef ref;
  if (r.value().is_string()) {
    ref.names.push_back(r.as_string());
  } else if (r.value().is_array() && !r.value().empty()) {
    for (std::size_t i = 0; i < r.value().size(); ++i) ref.names.push_back(r.at(i).as_string());
  } else {
    r.fail("expected a marker or point name, or an array of names (their mean)",
           "use \"NAME\" or [\"NAME1\", \"NAME2\"]");
  }
  return ref;
}

int read_axis_name(const JsonReader& r) {
  const std::string a = r.as_string();
  if (a == "x") return 0;
  if (a == "y") return 1;
  if (a == "z") return 2;
  r.fail("unknown axis '" + a + "'", "use \"x\", \"y\" or \"z\"");
}

FrameSpec read_frame(const JsonReader& r) {
  if (!r.value().is_array() || r.value().size() != 2)
    r.fail("a frame is an array of two axes",
           "use [{\"axis\": \"y\", \"from\": A, \"to\": B}, {\"axis\": \"x\", \"from\": C, "
           "\"to\": D}]: the first axis is exact, the second is made orthogonal to it");
  FrameSpec f;
  f.pointer = r.pointer();
  FrameAxis* axes[2] = {&f.primary, &f.secondary};
  for (std::size_t i = 0; i < 2; ++i) {
    const JsonReader a = r.at(i);
    a.only_keys({"axis", "from", "to"});
    axes[i]->axis = read_axis_name(a.at("axis"));
    axes[i]->from = read_ref(a.at("from"));
    axes[i]->to = read_ref(a.at("to"));
  }
  if (f.primary.axis == f.secondary.axis)
    r.at(1).at("axis").fail("both axes of the frame are the same", "name two different axes");
  return f;
}

struct Loader {
  const JsonReader root;
  CalibTemplate t;
  double scale = 1e-3;
  // Offset points (and segments) whose frame names a segment, resolved once
  // all segments are read.
  std::vector<std::pair<int, JsonReader>> named_frames;
  std::vector<std::pair<int, JsonReader>> named_segment_frames;
  // Every reference, checked once all names are known.
  std::vector<std::pair<std::string, std::string>> refs;  // name, pointer
  // The model's limits hold for a template too, checked as it is read (its
  // names are looked up one by one, so a larger one would cost minutes).
  std::vector<int> depth;  // per segment, from the root
  // Keypoint templates: the segment being read's level and weight (for its keypoints), and
  // every "rest_from" (name, pointer), checked once all points are known.
  int segment_level = 0;
  double segment_weight = 1.0;
  std::vector<std::pair<std::string, std::string>> rest_from_refs;

  void note_ref(const PointRef& ref, const JsonReader& where) { note_ref(ref, where.pointer()); }
  void note_ref(const PointRef& ref, const std::string& pointer) {
    for (const std::string& n : ref.names) refs.emplace_back(n, pointer);
  }

  const JsonReader* pending_segment_frame(int seg) const {
    for (const auto& [s, f] : named_segment_frames)
      if (s == seg) return &f;
    return nullptr;
  }

  void check_unique(const std::string& name, const JsonReader& where) {
    if (t.find_point(name) >= 0 || t.find_marker(name) >= 0)
      where.fail("the name '" + name + "' is used twice",
                 "give every point and marker of the template its own name");
  }

  void read_point(const JsonReader& p, const std::string& name, int seg) {
    p.only_keys({"at", "midpoint", "offset", "from", "frame", "regression", "side", "markers",
                 "description", "target", "rest", "rest_from", "optional"});
    PointDef d;
    d.name = name;
    d.segment = seg;
    d.pointer = p.pointer();
    const int rules =
        int(p.has("at")) + int(p.has("midpoint")) + int(p.has("offset")) + int(p.has("regression"));
    if (rules == 0 && t.kind == TemplateKind::keypoints && p.has("rest")) {
      // A point no keypoint sees (a trunk joint): fixed at its nominal rest vector. It is
      // placed through a static-only marker of its own, which the rest posture carries.
      d.fixed = true;
      d.refs.push_back(PointRef{{"~" + name}});
      MarkerDef m;
      m.name = "~" + name;
      m.segment = seg;
      m.static_only = true;
      m.pointer = p.pointer();
      t.markers.push_back(std::move(m));
      read_keypoint_fields(p, d);
      t.points.push_back(std::move(d));
      return;
    }
    if (rules != 1)
      p.fail("a point needs exactly one rule",
             "give one of \"at\", \"midpoint\", \"offset\", "
             "\"regression\"");
    if (p.has("at")) {
      d.rule = PointRule::at;
      d.refs.push_back(read_ref(p.at("at")));
      note_ref(d.refs.back(), p.at("at"));
    } else if (p.has("midpoint")) {
      d.rule = PointRule::midpoint;
      const JsonReader m = p.at("midpoint");
      if (!m.value().is_array() || m.value().size() < 2)
        m.fail("a midpoint needs two or more names", "use [\"A\", \"B\"]");
      for (std::size_t i = 0; i < m.value().size(); ++i) {
        d.refs.push_back(read_ref(m.at(i)));
        note_ref(d.refs.back(), m.at(i));
      }
    } else if (p.has("offset")) {
      d.rule = PointRule::offset;
      d.offset_m = p.at("offset").as_vec3() * scale;
      d.refs.push_back(read_ref(p.at("from")));
      note_ref(d.refs.back(), p.at("from"));
      if (p.has("frame")) {
        const JsonReader f = p.at("frame");
        if (f.value().is_string()) {
          named_frames.emplace_back(static_cast<int>(t.points.size()), f);
        } else {
          t.frames.push_back(read_frame(f));
          d.frame = static_cast<int>(t.frames.size()) - 1;
        }
      } else if (t.segments[seg].frame >= 0) {
        d.frame = t.segments[seg].frame;
      } else if (const JsonReader* named = pending_segment_frame(seg)) {
        named_frames.emplace_back(static_cast<int>(t.points.size()), *named);
      } else {
        p.fail("an offset needs a frame and segment '" + t.segments[seg].name + "' has none",
               "add \"frame\" here or to the segment (an array of two axes), or name the "
               "segment whose frame to use");
      }
    } else {
      d.rule = PointRule::regression;
      const JsonReader r = p.at("regression");
      const std::string kind = r.as_string();
      if (kind != "harrington2007")
        r.fail("unknown regression '" + kind + "'", "use \"harrington2007\"");
      d.regression = HipRegression::harrington2007;
      const JsonReader side = p.at("side");
      const std::string s = side.as_string();
      if (s != "right" && s != "left") side.fail("unknown side '" + s + "'", "use right or left");
      d.right = s == "right";
      const JsonReader m = p.at("markers");
      m.only_keys({"r_asis", "l_asis", "sacrum", "r_psis", "l_psis"});
      d.r_asis = read_ref(m.at("r_asis"));
      d.l_asis = read_ref(m.at("l_asis"));
      note_ref(d.r_asis, m.at("r_asis"));
      note_ref(d.l_asis, m.at("l_asis"));
      if (m.has("sacrum") == (m.has("r_psis") || m.has("l_psis")))
        m.fail("the posterior pelvis is missing or given twice",
               "give either \"sacrum\" or both \"r_psis\" and \"l_psis\"");
      if (m.has("sacrum")) {
        d.posterior = read_ref(m.at("sacrum"));
        note_ref(d.posterior, m.at("sacrum"));
      } else {
        // The mid-PSIS is the posterior reference of both regressions.
        d.posterior = read_ref(m.at("r_psis"));
        const PointRef l = read_ref(m.at("l_psis"));
        d.posterior.names.insert(d.posterior.names.end(), l.names.begin(), l.names.end());
        note_ref(d.posterior, m);
      }
    }
    read_keypoint_fields(p, d);
    t.points.push_back(std::move(d));
  }

  // A keypoint template's point: a target keypoint ("at" one name, which becomes a tracked
  // marker of the segment) and its rest vector; a marker template has neither.
  void read_keypoint_fields(const JsonReader& p, PointDef& d) {
    const bool keypoints = t.kind == TemplateKind::keypoints;
    for (const char* key : {"target", "rest", "rest_from", "optional"})
      if (!keypoints && p.has(key))
        p.at(key).fail(std::string("\"") + key + "\" belongs to keypoint templates",
                       "add \"kind\": \"keypoints\" at the top, or remove it");
    if (!keypoints) return;
    if (d.rule != PointRule::at && d.rule != PointRule::midpoint)
      p.fail("a keypoint template's point is \"at\" a keypoint or a \"midpoint\"",
             "place joint centres on keypoints: there is no static trial for offsets or "
             "regressions");
    if (p.has("rest")) {
      d.has_rest = true;
      d.rest_m = p.at("rest").as_vec3() * scale;
      // Its direction is the segment's in the standing posture, its length the nominal one:
      // without either, the calibrated model's segment has no extent (said of the model).
      if (!(d.rest_m.norm() > 0.0))
        p.at("rest").fail("point '" + d.name + "' has a \"rest\" vector of length 0",
                          "give the vector from the segment's base (or \"rest_from\") to the "
                          "point in the standing posture, OpenSim axes, nominal length");
    } else if (d.rule == PointRule::at && !t.segments[d.segment].base.empty() &&
               !(d.segment == 0 && t.segments[0].base == d.name)) {
      p.fail("point '" + d.name + "' has no \"rest\" vector",
             "give \"rest\": [x, y, z] from the segment's base (or \"rest_from\") in the "
             "standing posture, OpenSim axes (x anterior, y up, z right), nominal length");
    }
    d.rest_from = p.get("rest_from", std::string());
    if (!d.rest_from.empty()) rest_from_refs.emplace_back(d.rest_from, p.at("rest_from").pointer());
    d.optional = p.get("optional", false);
    if (!p.has("target")) return;
    d.target = p.at("target").as_string();
    if (d.target != "joint" && d.target != "point")
      p.at("target").fail("unknown target '" + d.target + "'",
                          "use \"joint\" (a joint centre) or \"point\" (a segment point)");
    if (d.rule != PointRule::at || d.refs[0].names.size() != 1)
      p.at("target").fail("a target point is \"at\" exactly one keypoint",
                          "use \"at\": \"KEYPOINT\"");
    const std::string& keypoint = d.refs[0].names[0];
    if (keypoint == d.name)
      p.at("at").fail("the point and its keypoint are both named '" + keypoint + "'",
                      "name the point after what it is (e.g. \"r_knee\" at \"RKnee\")");
    check_unique(keypoint, p.at("at"));
    MarkerDef m;
    m.name = keypoint;
    m.segment = d.segment;
    m.level = segment_level;
    m.weight = segment_weight;
    m.pointer = p.at("at").pointer();
    t.markers.push_back(std::move(m));
  }

  void read_segment(const JsonReader& s) {
    s.only_keys({"name", "parent", "base", "level", "weight", "frame", "joint", "points", "markers",
                 "description"});
    SegmentDef seg;
    seg.name = s.at("name").as_string();
    seg.pointer = s.pointer();
    if (t.find_segment(seg.name) >= 0)
      s.at("name").fail("segment '" + seg.name + "' is defined twice", "rename one of them");
    if (s.has("parent")) {
      const std::string parent = s.at("parent").as_string();
      seg.parent = t.find_segment(parent);
      if (seg.parent < 0)
        s.at("parent").fail("parent '" + parent + "' is not a segment listed before this one",
                            "list every segment after its parent");
    }
    seg.base = s.at("base").as_string();
    const int idx = static_cast<int>(t.segments.size());
    depth.push_back(seg.parent < 0 ? 1 : depth[seg.parent] + 1);
    if (seg.parent >= 0) ModelLimits::check_depth(s.at("parent"), seg.name, depth.back());
    ModelLimits::check_points(s, (s.has("points") ? s.at("points").value().size() : 0) +
                                     (s.has("markers") ? s.at("markers").value().size() : 0));
    if (s.has("frame")) {
      if (s.at("frame").value().is_string()) {
        named_segment_frames.emplace_back(idx, s.at("frame"));
      } else {
        t.frames.push_back(read_frame(s.at("frame")));
        seg.frame = static_cast<int>(t.frames.size()) - 1;
      }
    }
    if (s.has("joint")) {
      if (seg.parent < 0)
        s.at("joint").fail("the root segment has no parent joint",
                           "remove \"joint\" from the root segment");
      s.at("joint").expect_object();
      seg.joint = s.at("joint").value();
    }
    t.segments.push_back(seg);
    const int level = static_cast<int>(s.get("level", (long long)t.default_level, -1000, 1000));
    const double weight = s.get("weight", t.default_weight, 1e-9, 1e9);
    segment_level = level;
    segment_weight = weight;
    if (t.kind == TemplateKind::keypoints) {
      // The rest posture is built in OpenSim's axes, so every segment's frame is those axes.
      for (const char* key : {"frame", "markers"})
        if (s.has(key))
          s.at(key).fail(std::string("a keypoint template's segment has no \"") + key + "\"",
                         "its frame is the rest posture's axes (x anterior, y up, z right); "
                         "its keypoints are points with \"target\"");
    }

    if (s.has("points")) {
      const JsonReader pts = s.at("points");
      pts.expect_object();
      for (auto it = pts.value().begin(); it != pts.value().end(); ++it) {
        check_unique(it.key(), pts.at(it.key()));
        read_point(pts.at(it.key()), it.key(), idx);
      }
    }
    if (s.has("markers")) {
      const JsonReader ms = s.at("markers");
      ms.expect_object();
      for (auto it = ms.value().begin(); it != ms.value().end(); ++it) {
        const JsonReader m = ms.at(it.key());
        m.only_keys({"level", "weight", "static_only", "description"});
        check_unique(it.key(), m);
        MarkerDef d;
        d.name = it.key();
        d.segment = idx;
        d.level = static_cast<int>(m.get("level", (long long)level, -1000, 1000));
        d.weight = m.get("weight", weight, 1e-9, 1e9);
        d.static_only = m.get("static_only", false);
        d.pointer = m.pointer();
        t.markers.push_back(std::move(d));
        ModelLimits::check_markers(m, t.markers.size());
      }
    }
  }

  void check_tree(const JsonReader& segs) {
    for (std::size_t i = 1; i < t.segments.size(); ++i)
      if (t.segments[i].parent < 0)
        segs.at(i).fail("segment '" + t.segments[i].name + "' is a second root (it has no parent)",
                        "exactly one segment, the first, has no \"parent\": give it one");
    std::map<std::string, int> based;  // point -> the segment based on it
    for (std::size_t i = 0; i < t.segments.size(); ++i) {
      const SegmentDef& s = t.segments[i];
      const JsonReader base = segs.at(i).at("base");
      const int owner = s.parent < 0 ? static_cast<int>(i) : s.parent;
      const int p = t.find_point(s.base);
      if (p < 0 || t.points[p].segment != owner)
        base.fail(
            "base '" + s.base + "' is not a point of segment '" + t.segments[owner].name + "'",
            s.parent < 0 ? "define the root's base among its own \"points\""
                         : "define it in the parent's \"points\"");
      if (auto [it, fresh] = based.emplace(s.base, static_cast<int>(i)); !fresh)
        base.fail("point '" + s.base + "' is already the base of segment '" +
                      t.segments[it->second].name + "'",
                  "a joint links exactly two segments: define a separate point");
    }
  }

  void check_refs() {
    for (const auto& [name, pointer] : refs)
      if (t.find_point(name) < 0 && t.find_marker(name) < 0)
        throw ConfigError(t.file, pointer, "'" + name + "' is neither a point nor a marker",
                          "list the marker under a segment's \"markers\" (with \"static_only\": "
                          "true if only the static trial has it) or define the point");
  }

  // Points may be defined from other points; a cycle would never resolve.
  void check_cycles() {
    std::vector<int> state(t.points.size(), 0);  // 0 new, 1 visiting, 2 done
    std::function<void(int)> visit = [&](int i) {
      if (state[i] == 2) return;
      if (state[i] == 1)
        throw ConfigError(t.file, t.points[i].pointer,
                          "point '" + t.points[i].name + "' is defined from itself (a cycle)",
                          "define it from markers or from points that do not depend on it");
      state[i] = 1;
      const PointDef& d = t.points[i];
      std::vector<const PointRef*> deps;
      for (const PointRef& r : d.refs) deps.push_back(&r);
      if (d.rule == PointRule::regression) {
        deps.push_back(&d.r_asis);
        deps.push_back(&d.l_asis);
        deps.push_back(&d.posterior);
      }
      if (d.frame >= 0) {
        const FrameSpec& f = t.frames[d.frame];
        for (const PointRef* r :
             {&f.primary.from, &f.primary.to, &f.secondary.from, &f.secondary.to})
          deps.push_back(r);
      }
      for (const PointRef* r : deps)
        for (const std::string& n : r->names)
          if (const int p = t.find_point(n); p >= 0) visit(p);
      state[i] = 2;
    };
    for (std::size_t i = 0; i < t.points.size(); ++i) visit(static_cast<int>(i));
  }

  void load() {
    // The format first: a model or config given by mistake gets the clearest message.
    const JsonReader fmt = root.at("format");
    if (fmt.as_string() != "fabrikd-template/1")
      fmt.fail("unsupported format '" + fmt.as_string() + "'",
               "use \"fabrikd-template/1\" (is this a template?)");
    root.only_keys({"format", "kind", "name", "description", "units", "defaults", "segments",
                    "coordinates", "sensors", "lab_axes"});
    if (root.has("kind")) {
      const std::string kind = root.at("kind").as_string();
      if (kind == "keypoints") t.kind = TemplateKind::keypoints;
      else if (kind != "markers")
        root.at("kind").fail("unknown kind '" + kind + "'", "use \"markers\" or \"keypoints\"");
    }
    if (root.has("lab_axes")) t.lab_axes = read_lab_axes(root.at("lab_axes"));
    if (root.has("coordinates")) {
      root.at("coordinates").expect_object();
      t.coordinates = root.at("coordinates").value();
    }
    t.name = root.get("name", std::string("template"));
    t.description = root.get("description", std::string());
    scale = metres_per_unit(root.at("units"));
    if (root.has("defaults")) {
      const JsonReader d = root.at("defaults");
      d.only_keys({"level", "weight"});
      t.default_level = static_cast<int>(d.get("level", 0LL, -1000, 1000));
      t.default_weight = d.get("weight", 1.0, 1e-9, 1e9);
    }
    const JsonReader segs = root.at("segments");
    segs.expect_array();
    if (segs.value().empty()) segs.fail("no segments", "add at least one segment");
    ModelLimits::check_segments(segs);
    for (std::size_t i = 0; i < segs.value().size(); ++i) read_segment(segs.at(i));
    // A segment's frame may be another segment's (a clavicle's the torso's).
    for (const auto& [seg, f] : named_segment_frames) {
      const std::string other = f.as_string();
      const int s = t.find_segment(other);
      if (s < 0 || t.segments[s].frame < 0)
        f.fail("'" + other + "' is not a segment with a frame of its own",
               "name a segment that defines \"frame\" as two axes, or give the axes here");
      t.segments[seg].frame = t.segments[s].frame;
    }
    for (const auto& [point, f] : named_frames) {
      const std::string seg = f.as_string();
      const int s = t.find_segment(seg);
      if (s < 0 || t.segments[s].frame < 0)
        f.fail("'" + seg + "' is not a segment with a \"frame\"",
               "name a segment that defines \"frame\", or give the frame here");
      t.points[point].frame = t.segments[s].frame;
    }
    for (const FrameSpec& f : t.frames) {
      for (const FrameAxis* a : {&f.primary, &f.secondary}) {
        note_ref(a->from, f.pointer);
        note_ref(a->to, f.pointer);
      }
    }
    check_tree(segs);
    check_refs();
    for (const auto& [name, pointer] : rest_from_refs)
      if (t.find_point(name) < 0)
        throw ConfigError(t.file, pointer, "'" + name + "' is not a point of the template",
                          "name a point of the same segment, or its base");
    check_cycles();
    if (root.has("sensors")) {
      std::vector<std::string> names;
      for (const SegmentDef& sd : t.segments) names.push_back(sd.name);
      t.sensors = read_sensor_section(root.at("sensors"), names, false);
      // Without lab_axes a template's sensors' world is OpenSim's ground's: y up.
      resolve_world_up(root.at("sensors"), t.sensors,
                       t.lab_axes ? t.lab_axes->up_lab : LabAxes{}.up_lab);
    }
    for (const MarkerDef& m : t.markers)
      if (!m.static_only) return;
    root.at("segments")
        .fail("every marker is static_only: nothing would be tracked",
              "list the tracked markers of each segment");
  }
};

}  // namespace

CalibTemplate load_template(const nlohmann::json& doc, const std::string& file) {
  Loader l{JsonReader(doc, file), {}, 1e-3, {}, {}, {}, {}, 0, 1.0, {}};
  l.t.file = file;
  l.load();
  return std::move(l.t);
}

std::string keypoint_template_not_static(const std::string& template_path) {
  return template_path +
         " is a keypoint template: it calibrates from a movement trial or its nominal lengths";
}

std::string sensors_left_out(std::size_t sensors) {
  return "the template's " + std::to_string(sensors) +
         " orientation sensors are left out of the config";
}

CalibTemplate load_template_file(const std::string& path) {
  return load_template(JsonReader::parse_file(path), path);
}

}  // namespace fabrik::calib
