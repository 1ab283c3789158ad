// Orientation sensor calibration, as OpenSim's IMU placer does it: while the
// subject stands in a known pose (the model's rest posture), each sensor's
// reading gives its fixed rotation relative to its segment, and a base
// sensor's heading axis gives the heading between the sensors' world and the
// model's world.
//
// With S the sensors' world axes in the model's world (SensorWorld's
// rotation_deg), the base sensor's heading axis a (in its own frame), its
// reading q_b and its segment's front f (the anatomical x axis in the pose),
// both projected on the horizontal plane of the model's vertical u:
//   heading = the angle about u from (S q_b a) to f,
//   q_world_sensors = R_u(heading) S,
//   q_segment_sensor[k] = R_pose[segment k]^-1 q_world_sensors q_k.
// Then every sensor's reading in that pose gives back its segment's pose rotation.
#pragma once

#include <Eigen/Geometry>
#include <span>
#include <string>
#include <vector>

#include "config/sensors_json.hpp"
#include "io/orientation_table.hpp"
#include "solver/model.hpp"
#include "solver/posture.hpp"

namespace fabrik::calib {

struct SensorCalibration {
  SensorSection section;  // the spec with heading_rad and every rotation filled in
  // Per entry of the section: how far the mounting turns the sensor from its
  // segment's frame (degrees), for the report.
  std::vector<double> mounting_deg;
  std::vector<std::string> notes;  // sensors of the recording the spec does not use
};

// `names[i]` recorded `q_sensors_sensor[i]` in the calibration pose `pose`
// (segment rotations in the model's world). Throws CalibrationError when a
// sensor of the spec has no usable reading, or the heading axis is too close
// to the vertical to give a heading.
SensorCalibration calibrate_sensors(const SensorSection& spec, const Model& model,
                                    const Posture& pose, std::span<const std::string> names,
                                    std::span<const Eigen::Quaterniond> q_sensors_sensor);

// The posture a section's calibration_pose names: "rest", or "zero_angles"
// (each segment turned so that its anatomical frame is parallel to the
// world, joints connected, the root's base where the rest posture has it).
Posture calibration_posture(const Model& model, const std::string& pose);

// The same from a table recorded in the section's calibration pose: each sensor's
// rows are averaged (mean_rotation); spread_deg[k] is how far any row of
// entry k's sensor is from its mean (a subject who moved shows there).
SensorCalibration calibrate_sensors_from_table(const SensorSection& spec, const Model& model,
                                               const io::OrientationTable& table,
                                               std::vector<double>& spread_deg);

// Calibrates `spec` from `table` (calibrate_sensors_from_table), writes the
// result into `config`'s "sensors" and returns the report (sensor_report).
// The same sensors' world in `to`'s lab axes as `world` is in `from`'s (a template's world,
// written for OpenSim's y-up ground, on a subject calibrated in a z-up lab): its rotation
// turned with the lab, its up the lab's, its heading kept (about the turned up).
SensorWorld sensor_world_in_lab(SensorWorld world, const LabAxes& from, const LabAxes& to);

std::string calibrate_sensors_into(const SensorSection& spec, const Model& model,
                                   const io::OrientationTable& table,
                                   const std::string& table_name, nlohmann::ordered_json& config);

// What `fabrik calibrate` prints about the sensors.
std::string sensor_report(const SensorCalibration& c, std::span<const double> spread_deg,
                          const std::string& table_name, std::size_t rows);

// The mean of nearby rotations (signs aligned with the first, summed,
// normalised) and the largest angle of any of them from it (radians).
// NaN quaternions are skipped; none left gives a NaN mean.
Eigen::Quaterniond mean_rotation(std::span<const Eigen::Quaterniond> q, double* spread_rad);

}  // namespace fabrik::calib
