// Orientation sensors (IMUs, tracked rigid bodies) as targets of the Tracker.
// Each sensor is fixed to one segment. It measures its own frame's rotation in
// the sensors' world (a magnetic/gravity frame for an IMU, the mocap system's
// frame for a rigid body); two fixed rotations, found by calibration, turn
// that into the segment's desired rotation in the model's world:
//
//   q_world_segment = q_world_sensors * q_sensors_sensor * q_segment_sensor^-1
//
// q_world_sensors: the sensors' world in the model's world (an axis change,
// e.g. OpenSense's -90 deg about x from a z-up IMU world to OpenSim's y-up
// one, then a heading about the model's vertical); q_segment_sensor: the
// sensor's frame in its segment's frame. Solver types only, no allocation
// per frame.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "solver/model.hpp"
#include "solver/posture.hpp"
#include "solver/solve_types.hpp"

#include "tracking/tracking_settings.hpp"

namespace fabrik {

// The sensors' world in the model's world: first `rotation_xyz_rad`, space-fixed
// rotations about x, then y, then z (OpenSim's sensor_to_opensim_rotations),
// then `heading_rad` about the model's vertical `up` (a unit vector).
Eigen::Quaterniond sensors_to_world(const Eigen::Vector3d& rotation_xyz_rad,
                                    const Eigen::Vector3d& up, double heading_rad);

// A measured orientation that may be used: finite and of unit length within `tolerance`.
bool usable_quaternion(const Eigen::Quaterniond& q, double tolerance);

class SensorTargets {
 public:
  // Throws std::invalid_argument for a segment outside the model, a weight that is not
  // positive and finite, or a rotation that is not a finite non-zero quaternion.
  SensorTargets(const SensorSetup& setup, const Model& model);

  int size() const { return static_cast<int>(sensors_.size()); }
  const std::vector<SensorTarget>& sensors() const { return sensors_; }
  // One orientation target per sensor, in the same order.
  std::vector<OrientationTarget> solver_targets() const;

  // q_sensors_sensor[k], visible[k] belong to sensors()[k]. A sensor is occluded
  // when visible[k] is 0 or its quaternion is not usable (not finite, not unit
  // within 0.01: the decoder applies the configured tolerance before this).
  // Empty spans: every sensor occluded. Returns false (nothing changed) for other sizes.
  bool set_measured(std::span<const Eigen::Quaterniond> q_sensors_sensor,
                    std::span<const std::uint8_t> visible);
  // Desired segment rotations (model world) and their visibility, per sensor.
  std::span<const Eigen::Quaterniond> q_world_segment() const { return q_world_segment_; }
  std::span<const std::uint8_t> visible() const { return visible_; }
  std::span<const std::uint8_t> occluded() const { return occluded_; }
  int occluded_count() const { return occluded_count_; }

  // Angle between each measured sensor's desired rotation and its segment's
  // rotation in `posture` (NaN for occluded ones), and their summary.
  void measure(const Posture& posture);
  std::span<const double> error_rad() const { return error_rad_; }
  double rms_rad() const { return rms_rad_; }
  double max_rad() const { return max_rad_; }
  int worst() const { return worst_; }  // -1 if none measured

 private:
  std::vector<SensorTarget> sensors_;
  Eigen::Quaterniond q_world_sensors_;
  std::vector<Eigen::Quaterniond> q_sensor_segment_;  // per sensor: q_segment_sensor^-1
  std::vector<Eigen::Quaterniond> q_world_segment_;
  std::vector<std::uint8_t> visible_, occluded_;
  std::vector<double> error_rad_;
  int occluded_count_ = 0;
  double rms_rad_ = 0.0, max_rad_ = 0.0;
  int worst_ = -1;
};

}  // namespace fabrik
