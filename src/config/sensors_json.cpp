#include "sensors_json.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/format_number.hpp"
#include "config/lab_axes_json.hpp"
#include "solver/units.hpp"

namespace fabrik {

namespace {

std::string joined(const std::vector<std::string>& names) {
  std::string s;
  for (std::size_t i = 0; i < names.size() && i < 12; ++i) s += (i ? ", " : "") + names[i];
  if (names.size() > 12) s += ", ...";
  return s;
}

std::string read_axis_name(const JsonReader& r) {
  const std::string name = r.as_string();
  if (!is_axis_name(name))
    r.fail("'" + name + "' is not an axis", "write \"x\", \"y\" or \"z\", optionally with a sign (\"-z\")");
  return name;
}

}  // namespace

bool is_axis_name(const std::string& name) {
  std::string_view n = name;
  if (!n.empty() && (n.front() == '-' || n.front() == '+')) n.remove_prefix(1);
  return n == "x" || n == "y" || n == "z";
}

Eigen::Vector3d axis_vector(const std::string& name) {
  const double sign = !name.empty() && name.front() == '-' ? -1.0 : 1.0;
  const char a = name.empty() ? 'z' : name.back();
  return sign * Eigen::Vector3d::Unit(a == 'x' ? 0 : a == 'y' ? 1 : 2);
}

Eigen::Vector3d SensorWorld::up_vector() const { return axis_vector(up); }

Eigen::Quaterniond SensorWorld::q_world_sensors() const {
  return sensors_to_world(rotation_xyz_rad, up_vector(), heading_rad);
}

void resolve_world_up(const JsonReader& sensors, SensorSection& section,
                      const Eigen::Vector3d& up_lab) {
  if (!sensors.has("world") || !sensors.at("world").has("up")) {
    section.world.up = signed_axis_name(up_lab);
    return;
  }
  if (section.world.up_vector() == up_lab) return;
  sensors.at("world").at("up").fail(
      "the model's vertical is its lab_axes' up (" + signed_axis_name(up_lab) + "), not " +
          section.world.up,
      "give \"up\" as the lab_axes' up; the sensors' own world (OpenSense's z-up) is turned "
      "onto the model's by \"rotation_deg\" ([-90, 0, 0] in degrees for OpenSense on a y-up "
      "model). A config calibrated with the other up (before 2026-12-05): calibrate it again from "
      "its template (fabrik calibrate --template T.json --static S --static-orientations "
      "FILE.sto)");
}

SensorSection read_sensor_section(const JsonReader& sensors,
                                  const std::vector<std::string>& segments, bool rotations) {
  sensors.expect_object();
  sensors.only_keys({"world", "default", "orientations", "calibration_pose", "description"});
  SensorSection out;
  if (sensors.has("calibration_pose")) {
    const JsonReader p = sensors.at("calibration_pose");
    out.calibration_pose = p.as_string();
    if (out.calibration_pose != "zero_angles" && out.calibration_pose != "rest")
      p.fail("unknown calibration pose '" + out.calibration_pose + "'",
             "use \"zero_angles\" (OpenSim's default pose) or \"rest\" (the model's rest posture)");
  }
  if (sensors.has("world")) {
    const JsonReader w = sensors.at("world");
    w.only_keys({"rotation_deg", "up", "heading_deg", "heading_from"});
    if (w.has("rotation_deg")) {
      const Eigen::Vector3d deg = w.at("rotation_deg").as_vec3();
      if (deg.cwiseAbs().maxCoeff() > 360.0)
        w.at("rotation_deg").fail("angles beyond 360 deg", "give each angle in [-360, 360] degrees");
      // OpenSim's sensor_to_opensim_rotations are radians: -1.5708 copied here turned the
      // sensors' world by 1.6 deg, with no word. No one means 90 deg's radians in degrees.
      constexpr double kQuarterTurn_rad = std::numbers::pi / 2.0;
      for (int k = 0; k < 3; ++k) {
        const double turns = std::round(std::abs(deg[k]) / kQuarterTurn_rad);
        if (turns >= 1.0 && turns <= 4.0 &&
            std::abs(std::abs(deg[k]) - turns * kQuarterTurn_rad) < 0.01)  // 3.14 too
          w.at("rotation_deg")
              .fail("angle " + format_number("%.9g", deg[k]) +
                        " is a multiple of 90 deg in radians (OpenSim's "
                        "sensor_to_opensim_rotations are radians)",
                    "give degrees: " + format_number("%.9g", std::copysign(turns * 90.0, deg[k])) +
                        " for " + format_number("%.9g", deg[k]));
      }
      out.world.rotation_xyz_rad = deg * kRadPerDeg;
    }
    if (w.has("up")) out.world.up = read_axis_name(w.at("up"));
    out.world.heading_rad = w.get("heading_deg", 0.0, -360.0, 360.0) * kRadPerDeg;
    if (w.has("heading_from") && !w.at("heading_from").value().is_null()) {
      const JsonReader h = w.at("heading_from");
      h.only_keys({"sensor", "axis"});
      out.world.heading_sensor = h.at("sensor").as_string();
      if (h.has("axis")) out.world.heading_axis = read_axis_name(h.at("axis"));
    }
  }
  SensorEntry base;
  if (sensors.has("default")) {
    const JsonReader d = sensors.at("default");
    d.only_keys({"level", "weight"});
    base.level = static_cast<int>(d.get("level", 0LL, -1000LL, 1000LL));
    base.weight = d.get("weight", 1.0, 1e-9, 1e9);
  }
  if (sensors.has("orientations")) {
    const JsonReader list = sensors.at("orientations");
    list.expect_object();
    for (auto it = list.value().begin(); it != list.value().end(); ++it) {
      const JsonReader e = list.at(it.key());
      if (rotations)
        e.only_keys({"segment", "level", "weight", "rotation", "description"});
      else
        e.only_keys({"segment", "level", "weight", "description"});
      SensorEntry s = base;
      s.sensor = it.key();
      s.pointer = e.pointer();
      s.segment = e.at("segment").as_string();
      if (std::find(segments.begin(), segments.end(), s.segment) == segments.end())
        e.at("segment").fail("there is no segment '" + s.segment + "'",
                             "name one of the segments: " + joined(segments));
      s.level = static_cast<int>(e.get("level", static_cast<long long>(s.level), -1000LL, 1000LL));
      s.weight = e.get("weight", s.weight, 1e-9, 1e9);
      if (e.has("rotation")) {
        const JsonReader r = e.at("rotation");
        r.expect_array();
        if (r.value().size() != 4)
          r.fail("expected [w, x, y, z], got " + std::to_string(r.value().size()) + " numbers",
                 "give the sensor's frame in the segment's frame as a unit quaternion");
        const Eigen::Quaterniond q(r.at(0).as_number(), r.at(1).as_number(), r.at(2).as_number(),
                                   r.at(3).as_number());
        if (std::abs(q.norm() - 1.0) > 1e-3)
          r.fail("the quaternion's length is " + std::to_string(q.norm()) + ", not 1",
                 "give a unit quaternion [w, x, y, z] (fabrik calibrate writes one)");
        s.q_segment_sensor = q.normalized();
        s.has_rotation = true;
      }
      out.entries.push_back(s);
    }
  }
  const auto& e = out.entries;
  if (!out.world.heading_sensor.empty() &&
      std::none_of(e.begin(), e.end(),
                   [&](const SensorEntry& s) { return s.sensor == out.world.heading_sensor; }))
    sensors.at("world").at("heading_from").at("sensor").fail(
        "'" + out.world.heading_sensor + "' is not one of the sensors",
        "name a sensor listed under \"orientations\", or remove \"heading_from\"");
  return out;
}

SensorSetup sensor_setup(const SensorSection& section, const Model& model) {
  SensorSetup setup;
  setup.q_world_sensors = section.world.q_world_sensors();
  for (const SensorEntry& e : section.entries) {
    SensorTarget t;
    t.sensor = e.sensor;
    t.segment = model.find_segment(e.segment);
    t.level = e.level;
    t.weight = e.weight;
    t.q_segment_sensor = e.q_segment_sensor;
    setup.sensors.push_back(t);
  }
  return setup;
}

nlohmann::ordered_json sensor_section_json(const SensorSection& section) {
  const auto round = [](double v, double scale) { return std::round(v * scale) / scale; };
  nlohmann::ordered_json world;
  world["rotation_deg"] = {round(section.world.rotation_xyz_rad.x() * kDegPerRad, 1e9),
                           round(section.world.rotation_xyz_rad.y() * kDegPerRad, 1e9),
                           round(section.world.rotation_xyz_rad.z() * kDegPerRad, 1e9)};
  world["up"] = section.world.up;
  world["heading_deg"] = round(section.world.heading_rad * kDegPerRad, 1e6);
  if (!section.world.heading_sensor.empty())
    world["heading_from"] = {{"sensor", section.world.heading_sensor},
                             {"axis", section.world.heading_axis}};
  nlohmann::ordered_json list = nlohmann::ordered_json::object();
  for (const SensorEntry& e : section.entries) {
    nlohmann::ordered_json j;
    j["segment"] = e.segment;
    j["level"] = e.level;
    j["weight"] = e.weight;
    const Eigen::Quaterniond& q = e.q_segment_sensor;
    j["rotation"] = {round(q.w(), 1e12), round(q.x(), 1e12), round(q.y(), 1e12),
                     round(q.z(), 1e12)};
    list[e.sensor] = j;
  }
  return {{"calibration_pose", section.calibration_pose}, {"world", world}, {"orientations", list}};
}

}  // namespace fabrik
