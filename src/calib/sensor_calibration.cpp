#include "sensor_calibration.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "calibrate.hpp"
#include "config/lab_axes_json.hpp"
#include "solver/units.hpp"

namespace fabrik::calib {

namespace {

// Below this horizontal share (sin of the angle to the vertical: 10 deg), an
// axis has no heading worth the name.
constexpr double kMinHorizontal = 0.17;

Eigen::Vector3d horizontal(const Eigen::Vector3d& v, const Eigen::Vector3d& up) {
  return v - up * up.dot(v);
}

}  // namespace

Eigen::Quaterniond mean_rotation(std::span<const Eigen::Quaterniond> q, double* spread_rad) {
  Eigen::Vector4d sum = Eigen::Vector4d::Zero();
  const Eigen::Quaterniond* first = nullptr;
  for (const Eigen::Quaterniond& r : q) {
    if (!r.coeffs().allFinite() || r.norm() < 0.5) continue;
    if (!first) first = &r;
    const double sign = first->coeffs().dot(r.coeffs()) < 0.0 ? -1.0 : 1.0;
    sum += sign * r.normalized().coeffs();
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (!first || sum.norm() < 1e-12) {
    if (spread_rad) *spread_rad = nan;
    return Eigen::Quaterniond(nan, nan, nan, nan);
  }
  Eigen::Quaterniond mean;
  mean.coeffs() = sum.normalized();
  if (spread_rad) {
    *spread_rad = 0.0;
    for (const Eigen::Quaterniond& r : q)
      if (r.coeffs().allFinite() && r.norm() >= 0.5)
        *spread_rad = std::max(*spread_rad, mean.angularDistance(r.normalized()));
  }
  return mean;
}

SensorCalibration calibrate_sensors(const SensorSection& spec, const Model& model,
                                    const Posture& pose, std::span<const std::string> names,
                                    std::span<const Eigen::Quaterniond> q_sensors_sensor) {
  SensorCalibration out;
  out.section = spec;
  SensorWorld& world = out.section.world;
  const auto reading = [&](const std::string& sensor) -> const Eigen::Quaterniond* {
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == sensor && q_sensors_sensor[i].coeffs().allFinite() &&
          std::abs(q_sensors_sensor[i].norm() - 1.0) < 0.01)
        return &q_sensors_sensor[i];
    return nullptr;
  };
  // As OpenSense's IMU placer, the sensors the recording has are placed; one without a
  // reading is left out of the config, said. The heading's sensor cannot be.
  std::string missing;
  std::erase_if(out.section.entries, [&](const SensorEntry& e) {
    if (reading(e.sensor)) return false;
    missing += (missing.empty() ? "" : ", ") + e.sensor;
    return true;
  });
  const std::string fix = " (the recording has " + std::to_string(names.size()) +
                          " sensors). Fix: record every sensor of the template, or remove the "
                          "missing ones from its \"sensors\"";
  if (out.section.entries.empty())
    throw CalibrationError(
        "no usable orientation in the calibration pose for any sensor: " + missing + fix);
  if (!world.heading_sensor.empty() && !reading(world.heading_sensor))
    throw CalibrationError("no usable orientation in the calibration pose for '" +
                           world.heading_sensor + "', the heading's sensor (heading_from)" + fix);
  if (!missing.empty())
    out.notes.push_back("no usable orientation in the calibration pose for: " + missing +
                        ": left out of the config (its segments follow markers or the "
                        "calibration's posture)");
  for (const std::string& name : names)
    if (std::none_of(spec.entries.begin(), spec.entries.end(),
                     [&](const SensorEntry& e) { return e.sensor == name; }))
      out.notes.push_back("sensor '" + name + "' is not in the template: ignored");

  const Eigen::Vector3d up = world.up_vector();
  if (!world.heading_sensor.empty()) {
    const auto base = std::find_if(spec.entries.begin(), spec.entries.end(), [&](const auto& e) {
      return e.sensor == world.heading_sensor;
    });
    const int s = model.find_segment(base->segment);
    const Eigen::Quaterniond axes = sensors_to_world(world.rotation_xyz_rad, up, 0.0);
    const Eigen::Vector3d a =
        horizontal(axes * *reading(base->sensor) * axis_vector(world.heading_axis), up);
    const Eigen::Vector3d front = horizontal(
        pose.segments[s].q_world * model.segments[s].q_anatomical * Eigen::Vector3d::UnitX(), up);
    if (a.norm() < kMinHorizontal || front.norm() < kMinHorizontal)
      throw CalibrationError(
          "heading: " + std::string(a.norm() < kMinHorizontal
                                        ? "axis " + world.heading_axis + " of sensor '" +
                                              base->sensor + "' is"
                                        : "the front of segment '" + base->segment + "' is") +
          " within 10 deg of the vertical in the calibration pose. Fix: choose an axis that "
          "points forward (\"heading_from\"), or check \"rotation_deg\" and \"up\"");
    world.heading_rad = std::atan2(up.dot(a.cross(front)), a.dot(front));
  }
  const Eigen::Quaterniond q_world_sensors = world.q_world_sensors();
  for (SensorEntry& e : out.section.entries) {
    const int s = model.find_segment(e.segment);
    e.q_segment_sensor =
        (pose.segments[s].q_world.conjugate() * q_world_sensors * *reading(e.sensor)).normalized();
    e.has_rotation = true;
    out.mounting_deg.push_back(
        e.q_segment_sensor.angularDistance(Eigen::Quaterniond::Identity()) * kDegPerRad);
  }
  return out;
}

Posture calibration_posture(const Model& model, const std::string& pose) {
  Posture p = Posture::rest(model);
  if (pose == "rest") return p;
  // Zero angles are OpenSim's: each anatomical frame on the ground's axes, which the lab axes
  // place in the lab (a z-up lab's subject stands along z, not lying along y).
  const Eigen::Quaterniond q_lab_reference(model.lab_axes.r_reference_lab().transpose());
  for (std::size_t s = 0; s < model.segments.size(); ++s)
    p.segments[s].set_rotation(q_lab_reference * model.segments[s].q_anatomical.conjugate());
  connect_joints(model, p);
  return p;
}

SensorCalibration calibrate_sensors_from_table(const SensorSection& spec, const Model& model,
                                               const io::OrientationTable& table,
                                               std::vector<double>& spread_deg) {
  std::vector<Eigen::Quaterniond> column(table.rows()), mean(table.sensors.size());
  std::vector<double> spread(table.sensors.size(), 0.0);
  for (std::size_t k = 0; k < table.sensors.size(); ++k) {
    for (std::size_t r = 0; r < table.rows(); ++r) column[r] = table.at(r, k);
    mean[k] = mean_rotation(column, &spread[k]);
  }
  SensorCalibration c = calibrate_sensors(spec, model, calibration_posture(model, spec.calibration_pose), table.sensors, mean);
  spread_deg.clear();
  for (const SensorEntry& e : c.section.entries)
    spread_deg.push_back(spread[static_cast<std::size_t>(table.find(e.sensor))] * kDegPerRad);
  return c;
}

SensorWorld sensor_world_in_lab(SensorWorld world, const LabAxes& from, const LabAxes& to) {
  if (from == to) return world;
  const Eigen::Matrix3d axes =
      to.r_from(from) *
      sensors_to_world(world.rotation_xyz_rad, world.up_vector(), 0.0).toRotationMatrix();
  const Eigen::Vector3d zyx_rad = axes.eulerAngles(2, 1, 0);  // axes = Rz Ry Rx
  world.rotation_xyz_rad = {zyx_rad[2], zyx_rad[1], zyx_rad[0]};
  for (int k = 0; k < 3; ++k)  // 1e-14 rad of rounding is 0, written and printed as 0
    if (std::abs(world.rotation_xyz_rad[k]) < 1e-12) world.rotation_xyz_rad[k] = 0.0;
  world.up = signed_axis_name(to.up_lab);
  return world;
}

std::string calibrate_sensors_into(const SensorSection& spec, const Model& model,
                                   const io::OrientationTable& table,
                                   const std::string& table_name, nlohmann::ordered_json& config) {
  std::vector<double> spread_deg;
  const SensorCalibration c = calibrate_sensors_from_table(spec, model, table, spread_deg);
  config["sensors"] = sensor_section_json(c.section);
  return sensor_report(c, spread_deg, table_name, table.rows());
}

std::string sensor_report(const SensorCalibration& c, std::span<const double> spread_deg,
                          const std::string& table_name, std::size_t rows) {
  const SensorWorld& w = c.section.world;
  std::string out = "\nOrientation sensors (" + table_name + ", " + std::to_string(rows) +
                    (rows == 1 ? " row" : " rows averaged") +
                    "; the subject in the pose '" + c.section.calibration_pose + "'):\n";
  char line[256];
  std::snprintf(line, sizeof line,
                "  sensors' world: rotation_deg [%g, %g, %g], up %s, heading %.2f deg%s\n",
                w.rotation_xyz_rad.x() * kDegPerRad, w.rotation_xyz_rad.y() * kDegPerRad,
                w.rotation_xyz_rad.z() * kDegPerRad, w.up.c_str(), w.heading_rad * kDegPerRad,
                w.heading_sensor.empty()
                    ? " (as given)"
                    : (" (" + w.heading_sensor + " axis " + w.heading_axis + " forward)").c_str());
  out += line;
  out += "  sensor               segment          mounting deg   spread deg\n";
  for (std::size_t k = 0; k < c.section.entries.size(); ++k) {
    const SensorEntry& e = c.section.entries[k];
    std::snprintf(line, sizeof line, "  %-20s %-16s %12.1f %12.2f%s\n", e.sensor.c_str(),
                  e.segment.c_str(), c.mounting_deg[k], spread_deg[k],
                  spread_deg[k] > 5.0 ? "  (moved during the calibration pose?)" : "");
    out += line;
  }
  for (const std::string& n : c.notes) out += "  note: " + n + "\n";
  return out;
}

}  // namespace fabrik::calib
