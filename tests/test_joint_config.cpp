// Anatomical frames, joints and coordinates in the configuration: a model
// file's "frame", "joint" and "coordinates" as loaded; a template's frames
// written into the calibrated model, its joints and coordinates copied; and
// every mistake reported with the file, the JSON pointer and a fix.
#include <Eigen/Geometry>
#include <catch2/catch.hpp>
#include <cmath>
#include <functional>
#include <nlohmann/json.hpp>
#include <numbers>

#include "calib/calib_template.hpp"
#include "calib/calibrate.hpp"
#include "config/config_error.hpp"
#include "config/daemon_config.hpp"
#include "config/model_loader.hpp"
#include "io/marker_trial.hpp"
#include "solver/joint_angles.hpp"
#include "solver/posture.hpp"

using namespace fabrik;
using nlohmann::json;

namespace {

constexpr double kRad = std::numbers::pi / 180.0;

json model_doc() {
  return json::parse(R"({
    "format": "fabrikd-model/1", "name": "leg", "units": "mm",
    "segments": [
      {"name": "pelvis", "base": "origin", "frame": {"x": [1, 0, 0], "y": [0, 1, 0]},
       "points": {"hip": [0, -80, 90], "mid": [0, 10, 0]}},
      {"name": "thigh", "parent": "pelvis", "base": "hip",
       "frame": {"y": [0, 0.8, -0.6], "z": [0, 0.6, 0.8]},
       "joint": {"type": "ball", "range_deg": {"z": [-30, 120], "x": [-45, 30], "y": [-45, 45]}},
       "points": {"knee": [0, -400, 0]}},
      {"name": "shank", "parent": "thigh", "base": "knee",
       "joint": {"type": "hinge", "range_deg": {"z": [-135, 5]}},
       "points": {"ankle": [0, -400, 0]}}
    ],
    "coordinates": {
      "pelvis_tilt": {"segment": "pelvis", "relative_to": "world", "axis": "z"},
      "hip_adduction": {"segment": "thigh", "axis": "x", "sign": -1, "offset_deg": 10},
      "knee_angle": {"segment": "shank", "axis": "z"},
      "pelvis_ty": {"point": "mid", "axis": "y", "offset": 5}
    }})");
}

// One mistake: how to make it, and what the message must name.
struct Case {
  const char* what;
  std::function<void(json&)> edit;
  const char* pointer;
  const char* text;
};

// The message of the ConfigError `run` throws (fails the test if it throws none).
std::string error_of(const std::function<void()>& run) {
  try {
    run();
  } catch (const ConfigError& e) {
    return e.what();
  }
  FAIL("accepted, but should have been rejected");
  return "";
}

// A pelvis, thigh and shank template with frames, joints and coordinates.
json template_doc() {
  return json::parse(R"({
    "format": "fabrikd-template/1", "name": "leg", "units": "mm",
    "segments": [
      {"name": "pelvis", "base": "origin",
       "frame": [{"axis": "z", "from": "LASI", "to": "RASI"},
                 {"axis": "x", "from": "SACR", "to": ["RASI", "LASI"]}],
       "points": {
         "origin": {"midpoint": ["RASI", "LASI"]},
         "r_hip": {"regression": "harrington2007", "side": "right",
                   "markers": {"r_asis": "RASI", "l_asis": "LASI", "sacrum": "SACR"}}},
       "markers": {"RASI": {}, "LASI": {}, "SACR": {}}},
      {"name": "r_thigh", "parent": "pelvis", "base": "r_hip",
       "frame": [{"axis": "y", "from": "r_knee", "to": "r_hip"},
                 {"axis": "z", "from": "RKNM", "to": "RKNE"}],
       "joint": {"type": "ball", "range_deg": {"z": [-30, 120], "x": [-45, 30], "y": [-45, 45]}},
       "points": {"r_knee": {"midpoint": ["RKNE", "RKNM"]}},
       "markers": {"RTHI": {}, "RKNE": {}, "RKNM": {"static_only": true}}},
      {"name": "r_shank", "parent": "r_thigh", "base": "r_knee",
       "frame": [{"axis": "y", "from": "r_ankle", "to": "r_knee"},
                 {"axis": "z", "from": "RANM", "to": "RANK"}],
       "joint": {"type": "hinge", "range_deg": {"z": [-135, 5]}},
       "points": {"r_ankle": {"midpoint": ["RANK", "RANM"]}},
       "markers": {"RTIB": {}, "RANK": {}, "RANM": {"static_only": true}}},
      {"name": "r_foot", "parent": "r_shank", "base": "r_ankle", "frame": "r_shank",
       "joint": {"type": "universal", "range_deg": {"z": [-50, 20], "x": [-15, 35]}},
       "markers": {"RHEE": {}, "RTOE": {}}}
    ],
    "coordinates": {
      "hip_flexion_r": {"segment": "r_thigh", "axis": "z"},
      "knee_angle_r": {"segment": "r_shank", "axis": "z"},
      "ankle_angle_r": {"segment": "r_foot", "axis": "z"},
      "pelvis_tx": {"point": "origin", "axis": "x"}
    }})");
}

// A static trial of the template's markers (mm), ten identical frames.
io::MarkerTrial static_trial() {
  const std::vector<std::pair<std::string, Eigen::Vector3d>> mm = {
      {"RASI", {0, 1000, 120}},  {"LASI", {0, 1000, -120}}, {"SACR", {-150, 1000, 0}},
      {"RTHI", {40, 750, 140}},  {"RKNE", {10, 500, 150}},  {"RKNM", {-10, 505, 50}},
      {"RTIB", {40, 300, 125}},  {"RANK", {-5, 100, 140}},  {"RANM", {5, 110, 60}},
      {"RHEE", {-60, 60, 100}},  {"RTOE", {150, 40, 110}}};
  io::MarkerTrial t;
  t.rate_hz = 100.0;
  for (const auto& [name, p] : mm) t.labels.push_back(name);
  for (int f = 0; f < 10; ++f)
    for (const auto& [name, p] : mm) t.positions_m.push_back(p * 1e-3);
  return t;
}

calib::CalibrationResult calibrate_template(const json& doc) {
  const calib::CalibTemplate t = calib::load_template(doc, "leg.json");
  return calib::calibrate(t, static_trial(), "static.trc");
}


Eigen::Vector3d axis_of(const nlohmann::ordered_json& seg, const char* name) {
  const auto& a = seg["frame"][name];
  return {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
}

}  // namespace

TEST_CASE("A model's frames, joints and coordinates load as written", "[loader][joints]") {
  const Model m = load_model(model_doc(), "leg.json");
  const Segment& pelvis = m.segments[m.find_segment("pelvis")];
  const Segment& thigh = m.segments[m.find_segment("thigh")];
  const Segment& shank = m.segments[m.find_segment("shank")];
  CHECK(pelvis.q_anatomical.angularDistance(Eigen::Quaterniond::Identity()) < 1e-12);
  // Two axes given: the third completes a right-handed frame.
  const Eigen::Matrix3d r = thigh.q_anatomical.toRotationMatrix();
  CHECK((r.col(1) - Eigen::Vector3d(0, 0.8, -0.6)).norm() < 1e-12);
  CHECK((r.col(2) - Eigen::Vector3d(0, 0.6, 0.8)).norm() < 1e-12);
  CHECK((r.col(0) - Eigen::Vector3d(1, 0, 0)).norm() < 1e-12);
  CHECK(thigh.joint.type == JointType::ball);
  CHECK(thigh.joint.min_rad[0] == Approx(-30 * kRad));  // index 0: z
  CHECK(thigh.joint.max_rad[1] == Approx(30 * kRad));   // index 1: x
  CHECK(thigh.joint.min_rad[2] == Approx(-45 * kRad));  // index 2: y
  CHECK(shank.joint.type == JointType::hinge);
  CHECK(shank.joint.max_rad[0] == Approx(5 * kRad));
  // A hinge holds x and y at their rest values: the frames' relative rotation at rest.
  CHECK(shank.joint.min_rad[1] == shank.joint.max_rad[1]);
  // The thigh frame is the world turned by -asin(0.6) about x; the shank has the world frame.
  CHECK(shank.joint.rest_rad[1] == Approx(std::asin(0.6)));
  CHECK(pelvis.joint.type == JointType::free);

  REQUIRE(m.coordinates.size() == 4);
  const Coordinate& tilt = m.coordinates[m.find_coordinate("pelvis_tilt")];
  CHECK(tilt.relative_to == -1);
  CHECK(tilt.angle == 0);
  const Coordinate& add = m.coordinates[m.find_coordinate("hip_adduction")];
  CHECK(add.relative_to == m.find_segment("pelvis"));  // default: the parent
  CHECK(add.angle == 1);
  CHECK(add.sign == -1.0);
  CHECK(add.offset == Approx(10 * kRad));
  const Coordinate& ty = m.coordinates[m.find_coordinate("pelvis_ty")];
  CHECK(ty.kind == CoordinateKind::translation);
  CHECK(ty.point == m.find_point("mid"));
  CHECK(ty.axis == 1);
  CHECK(ty.offset == Approx(0.005));  // model units (mm) to metres
}

TEST_CASE("A coordinate is sign times (angle + offset), each relative to its own reference",
          "[joints][coordinates]") {
  // The thigh's angles relative to the pelvis and, listed right after them,
  // relative to the world: consecutive coordinates of one segment that must
  // not share angles computed for another reference.
  json d = model_doc();
  d["coordinates"]["hip_flexion"] = {{"segment", "thigh"}, {"axis", "z"}};
  d["coordinates"]["hip_world_z"] = {{"segment", "thigh"}, {"relative_to", "world"}, {"axis", "z"}};
  const Model m = load_model(d, "leg.json");
  const int flexion = m.find_coordinate("hip_flexion"), world_z = m.find_coordinate("hip_world_z");
  REQUIRE(std::abs(flexion - world_z) == 1);

  // Pelvis turned 20 deg about z, thigh 50 deg: the thigh is 30 deg about z
  // from the pelvis. Its anatomical frame is its segment frame turned by
  // -asin(0.6) about x (frame y = (0, 0.8, -0.6)), so relative to the pelvis
  // the anatomical rotation is Rz(30 deg) Rx(-asin 0.6) Ry(0), and relative to
  // the world Rz(50 deg) Rx(-asin 0.6) Ry(0).
  const double pelvis_rad = 20 * kRad, thigh_rad = 50 * kRad;
  Posture p = Posture::rest(m);
  const int pelvis = m.find_segment("pelvis");
  p.segments[pelvis].set_rotation(
      Eigen::Quaterniond(Eigen::AngleAxisd(pelvis_rad, Eigen::Vector3d::UnitZ())));
  p.segments[m.find_segment("thigh")].set_rotation(
      Eigen::Quaterniond(Eigen::AngleAxisd(thigh_rad, Eigen::Vector3d::UnitZ())));
  std::vector<double> values(m.coordinates.size());
  coordinate_values(m, p, values);

  const double adduction_raw_rad = -std::asin(0.6);
  CHECK(values[flexion] == Approx(thigh_rad - pelvis_rad));
  CHECK(values[world_z] == Approx(thigh_rad));
  CHECK(values[m.find_coordinate("pelvis_tilt")] == Approx(pelvis_rad));
  // hip_adduction: sign -1 and offset 10 deg, the offset added before the sign.
  CHECK(values[m.find_coordinate("hip_adduction")] == Approx(-(adduction_raw_rad + 10 * kRad)));
  // pelvis_ty: the world y of "mid" (10 mm up the turned pelvis) plus 5 mm.
  const double mid_y_m = p.segments[pelvis].base_world_m.y() + 0.010 * std::cos(pelvis_rad);
  CHECK(values[m.find_coordinate("pelvis_ty")] == Approx(mid_y_m + 0.005));
}

TEST_CASE("Each mistake in a model's frames, joints or coordinates has its own message",
          "[loader][joints]") {
  const std::vector<Case> cases = {
      {"one axis", [](json& d) { d["segments"][1]["frame"] = {{"x", {1, 0, 0}}}; },
       "at /segments/1/frame:", "a frame needs at least two of its axes"},
      {"not at right angles",
       [](json& d) { d["segments"][1]["frame"] = {{"x", {1, 0, 0}}, {"y", {1, 1, 0}}}; },
       "at /segments/1/frame:", "not at right angles or not right-handed"},
      {"left-handed",
       [](json& d) {
         d["segments"][1]["frame"] = {{"x", {1, 0, 0}}, {"y", {0, 1, 0}}, {"z", {0, 0, -1}}};
       },
       "at /segments/1/frame:", "right-handed"},
      {"zero axis",
       [](json& d) { d["segments"][1]["frame"] = {{"x", {0, 0, 0}}, {"y", {0, 1, 0}}}; },
       "at /segments/1/frame/x:", "the axis has no direction"},
      {"unknown joint type", [](json& d) { d["segments"][1]["joint"]["type"] = "balll"; },
       "at /segments/1/joint/type:", "ball"},
      {"hinge with an x range",
       [](json& d) { d["segments"][2]["joint"]["range_deg"]["x"] = {-5, 5}; },
       "at /segments/2/joint/range_deg/x:", "a hinge joint holds its x angle at rest"},
      {"min above max", [](json& d) { d["segments"][2]["joint"]["range_deg"]["z"] = {5, -135}; },
       "at /segments/2/joint/range_deg/z:", "min is larger than max"},
      {"x beyond 90",
       [](json& d) { d["segments"][1]["joint"]["range_deg"]["x"] = {-100, 30}; },
       "at /segments/1/joint/range_deg/x/0:", "90"},
      {"unknown joint field", [](json& d) { d["segments"][1]["joint"]["rang_deg"] = json::object(); },
       "at /segments/1/joint/rang_deg:", "did you mean 'range_deg'"},
      {"joint on the root", [](json& d) { d["segments"][0]["joint"] = {{"type", "ball"}}; },
       "at /segments/0/joint:", "root"},
      {"coordinate of an unknown segment",
       [](json& d) { d["coordinates"]["knee_angle"]["segment"] = "shin"; },
       "at /coordinates/knee_angle/segment:", "the model has no segment 'shin'"},
      {"coordinate relative to an unknown segment",
       [](json& d) { d["coordinates"]["knee_angle"]["relative_to"] = "femur"; },
       "at /coordinates/knee_angle:", "unknown segment 'femur'"},
      {"coordinate of an unknown point",
       [](json& d) { d["coordinates"]["pelvis_ty"]["point"] = "middle"; },
       "at /coordinates/pelvis_ty:", "unknown point 'middle'"},
      {"coordinate axis", [](json& d) { d["coordinates"]["knee_angle"]["axis"] = "w"; },
       "at /coordinates/knee_angle/axis:", "axis"},
      {"zero sign", [](json& d) { d["coordinates"]["knee_angle"]["sign"] = 0; },
       "at /coordinates/knee_angle/sign:", "the sign is zero"},
  };
  for (const Case& c : cases) {
    INFO(c.what);
    json d = model_doc();
    c.edit(d);
    const std::string msg = error_of([&] { load_model(d, "bad.json"); });
    CHECK_THAT(msg, Catch::StartsWith("bad.json: "));
    CHECK_THAT(msg, Catch::Contains(c.pointer));
    CHECK_THAT(msg, Catch::Contains(c.text));
    CHECK_THAT(msg, Catch::Contains("Fix: "));
  }
}

TEST_CASE("A template's frames go into the calibrated model, joints and coordinates are copied",
          "[calib][joints]") {
  const calib::CalibrationResult r = calibrate_template(template_doc());
  const auto& segs = r.model["segments"];
  REQUIRE(segs.size() == 4);
  // The thigh: y from the knee centre to the hip centre, z along the epicondyles made
  // orthogonal to it, both from the static trial.
  const Eigen::Vector3d knee = r.point_world_m("r_knee"), hip = r.point_world_m("r_hip");
  const Eigen::Vector3d y = (hip - knee).normalized();
  const Eigen::Vector3d epi = Eigen::Vector3d(20, -5, 100).normalized();  // RKNE - RKNM
  const Eigen::Vector3d z = (epi - epi.dot(y) * y).normalized();
  CHECK((axis_of(segs[1], "y") - y).norm() < 1e-6);
  CHECK((axis_of(segs[1], "z") - z).norm() < 1e-6);
  CHECK((axis_of(segs[1], "x") - y.cross(z)).norm() < 1e-6);
  // A frame named after another segment's is that segment's.
  for (const char* a : {"x", "y", "z"})
    CHECK((axis_of(segs[3], a) - axis_of(segs[2], a)).norm() < 1e-12);
  // Compared as text: the model is an ordered_json, the template a json.
  CHECK(nlohmann::json::parse(segs[2]["joint"].dump()) == template_doc()["segments"][2]["joint"]);
  CHECK(nlohmann::json::parse(r.model["coordinates"].dump()) == template_doc()["coordinates"]);

  // The written config loads, with the joints and the coordinates.
  const DaemonConfig c = load_daemon_config(r.config.dump(), "leg-config.json");
  const Model& m = *c.tracker.model;
  CHECK(m.segments[m.find_segment("r_shank")].joint.type == JointType::hinge);
  CHECK(m.segments[m.find_segment("r_foot")].joint.type == JointType::universal);
  CHECK(m.coordinates.size() == 4);
  // The foot's frame is the shank's at rest: the ankle starts at zero.
  const JointLimits& ankle = m.segments[m.find_segment("r_foot")].joint;
  for (double a : ankle.rest_rad) CHECK(a == Approx(0.0).margin(1e-9));
  // The hinge axis is the femur frame's z: the knee's held angles are the
  // shank frame's rest rotation relative to the thigh's.
  const JointLimits& knee_joint = m.segments[m.find_segment("r_shank")].joint;
  CHECK(knee_joint.min_rad[1] == knee_joint.max_rad[1]);
  CHECK(knee_joint.min_rad[2] == knee_joint.max_rad[2]);
}

TEST_CASE("Each mistake in a template's frames, joints or coordinates names the template",
          "[calib][joints]") {
  const std::vector<Case> at_load = {
      {"joint on the root", [](json& d) { d["segments"][0]["joint"] = {{"type", "ball"}}; },
       "at /segments/0/joint:", "the root segment has no parent joint"},
      {"joint not an object", [](json& d) { d["segments"][1]["joint"] = "ball"; },
       "at /segments/1/joint:", ""},
      {"frame of a segment without one", [](json& d) { d["segments"][3]["frame"] = "r_foot"; },
       "at /segments/3/frame:", "is not a segment with a frame of its own"},
      {"coordinates not an object", [](json& d) { d["coordinates"] = json::array(); },
       "at /coordinates:", ""},
  };
  // Joints and coordinates are checked when the model is built; the message
  // still points into the template, where the mistake is.
  const std::vector<Case> at_calibration = {
      {"hinge with a y range",
       [](json& d) { d["segments"][2]["joint"]["range_deg"]["y"] = {-5, 5}; },
       "at /segments/2/joint/range_deg/y:", "a hinge joint holds its y angle at rest"},
      {"universal range beyond 180",
       [](json& d) { d["segments"][3]["joint"]["range_deg"]["z"] = {-200, 20}; },
       "at /segments/3/joint/range_deg/z/0:", "180"},
      {"coordinate of an unknown segment",
       [](json& d) { d["coordinates"]["knee_angle_r"]["segment"] = "r_shin"; },
       "at /coordinates/knee_angle_r/segment:", "the model has no segment 'r_shin'"},
  };
  const auto check = [](const std::vector<Case>& cases, bool calibrate) {
    for (const Case& c : cases) {
      INFO(c.what);
      json d = template_doc();
      c.edit(d);
      const std::string msg = error_of([&] {
        if (calibrate)
          calibrate_template(d);
        else
          calib::load_template(d, "leg.json");
      });
      CHECK_THAT(msg, Catch::StartsWith("leg.json: "));
      CHECK_THAT(msg, Catch::Contains(c.pointer));
      CHECK_THAT(msg, Catch::Contains(c.text));
      CHECK_THAT(msg, Catch::Contains("Fix: "));
    }
  };
  check(at_load, false);
  check(at_calibration, true);
}

TEST_CASE("The shipped templates and the built-in model have frames, joints and coordinates",
          "[calib][joints]") {
  for (const char* name : {"gait2354", "vicon_upper_body"}) {
    INFO(name);
    const calib::CalibTemplate t = calib::load_template_file(std::string(FABRIK_SOURCE_DIR) +
                                                            "/config/templates/" + name + ".json");
    for (std::size_t s = 0; s < t.segments.size(); ++s) {
      INFO(t.segments[s].name);
      CHECK(t.segments[s].frame >= 0);
      if (s > 0) CHECK(t.segments[s].joint.is_object());
    }
    CHECK(t.coordinates.size() >= 10);
  }
  const Model body =
      load_model_file(std::string(FABRIK_SOURCE_DIR) + "/config/models/fullbody.json");
  for (std::size_t s = 1; s < body.segments.size(); ++s) {
    INFO(body.segments[s].name);
    CHECK(body.segments[s].joint.limited());
  }
  CHECK(body.segments[body.find_segment("r_shank")].joint.type == JointType::hinge);
  // Elbows flex and pronate: the forearm turns about its own axis too.
  const JointLimits& elbow = body.segments[body.find_segment("l_forearm")].joint;
  CHECK(elbow.type == JointType::ball);
  CHECK(elbow.max_rad[2] - elbow.min_rad[2] > 2.5);
  CHECK(body.find_coordinate("pro_sup_r") >= 0);
  CHECK(body.segments[body.find_segment("r_foot")].joint.type == JointType::universal);
  CHECK(body.find_coordinate("knee_angle_r") >= 0);
}
