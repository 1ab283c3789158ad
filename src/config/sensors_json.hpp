// The "sensors" section of daemon configs and templates (docs/daemon-config.md,
// docs/imu.md): which orientation sensor (IMU, rigid body)
// sits on which segment with which level and weight, its fixed rotation in
// the segment's frame, and how the sensors' world lies in the model's world.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "json_reader.hpp"
#include "tracking/sensor_targets.hpp"

namespace fabrik {

// How the sensors' world lies in the model's world ("world" object). The
// rotation from one to the other is sensors_to_world(rotation_xyz_rad, up, heading_rad).
struct SensorWorld {
  Eigen::Vector3d rotation_xyz_rad{0, 0, 0};  // "rotation_deg": space-fixed x, y, z (OpenSim's)
  std::string up = "y";                       // the model's vertical axis ("y", "-z", ...)
  double heading_rad = 0.0;                   // "heading_deg", about `up`
  // "heading_from": calibration turns the heading so that this sensor's
  // `heading_axis` points where its segment's front (anatomical x) points in
  // the calibration pose, as OpenSense's base IMU. Empty: heading_rad is kept.
  std::string heading_sensor;
  std::string heading_axis = "z";

  Eigen::Vector3d up_vector() const;
  Eigen::Quaterniond q_world_sensors() const;
};

// One sensor entry as written ("orientations" member).
struct SensorEntry {
  std::string sensor, segment;
  int level = 0;
  double weight = 1.0;
  bool has_rotation = false;  // "rotation": [w, x, y, z], the sensor's frame in the segment's
  Eigen::Quaterniond q_segment_sensor{Eigen::Quaterniond::Identity()};
  std::string pointer;  // where it was defined, for messages
};

struct SensorSection {
  SensorWorld world;
  // The pose the calibration recording was taken in: "zero_angles" (every
  // anatomical frame parallel to the world: all joint angles 0, OpenSim's
  // default pose, as OpenSense's IMU placer assumes) or "rest" (the model's
  // rest posture: the static trial's averaged posture for a calibrated model).
  std::string calibration_pose = "zero_angles";
  std::vector<SensorEntry> entries;  // in file order
};

// An axis name: "x", "y", "z", optionally signed ("-z", "+y"). Unit vector.
Eigen::Vector3d axis_vector(const std::string& name);
bool is_axis_name(const std::string& name);

// Reads a "sensors" object. `segments` are the names entries may use.
// `rotations`: whether entries may (config) or may not (template) carry "rotation".
SensorSection read_sensor_section(const JsonReader& sensors,
                                  const std::vector<std::string>& segments, bool rotations);

// `up` is the model's vertical, which the heading turns about, not the sensors' own (a z-up
// IMU world written there on a y-up model gave 17 deg of sensor error, no word): absent, it is
// `up_lab`, the model's (or template's) lab up; given otherwise, fails at "world"/"up".
void resolve_world_up(const JsonReader& sensors, SensorSection& section,
                      const Eigen::Vector3d& up_lab);

// The tracker's setup from a section whose segments name segments of `model`.
SensorSetup sensor_setup(const SensorSection& section, const Model& model);

// A section as a config writes it (heading and rotations included).
nlohmann::ordered_json sensor_section_json(const SensorSection& section);

}  // namespace fabrik
