// Simulated orientation sensors (IMUs) on a model's segments, for tests,
// benchmarks and `fabrik eval imu`: each sensor is mounted on its segment at
// a seeded random rotation, reports its frame's rotation in a sensors' world
// that is z-up and turned by a random heading (as an IMU's magnetic/gravity
// frame: OpenSense's convention, -90 deg about x from a y-up model world),
// with seeded Gaussian noise and a slow heading drift of its own. Solver
// types only: no I/O.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <random>
#include <span>
#include <vector>

#include "solver/posture.hpp"

namespace fabrik {

struct SensorNoise {
  double noise_rad = 0.0;         // per axis of the sensor frame, Gaussian
  double drift_rad_per_s = 0.0;   // each sensor drifts about the vertical at a rate within +-this
};

class SyntheticSensors {
 public:
  // One sensor per entry of `segments` (indices into the model's segments).
  // The model's vertical is +y.
  SyntheticSensors(std::vector<int> segments, SensorNoise noise, unsigned seed);

  const std::vector<int>& segments() const { return segments_; }
  // The truth of what calibration should find: each sensor's frame in its
  // segment's frame, and the sensors' world in the model's world.
  const std::vector<Eigen::Quaterniond>& q_segment_sensor() const { return q_segment_sensor_; }
  const Eigen::Quaterniond& q_world_sensors() const { return q_world_sensors_; }
  // The heading part of q_world_sensors (about the model's +y), radians.
  double heading_rad() const { return heading_rad_; }

  // What the sensors report on `posture` at time t (drift grows with t):
  // out[k] is sensor k's frame in the sensors' world, unit.
  void sample(const Posture& posture, double t_s, std::span<Eigen::Quaterniond> out);

 private:
  std::vector<int> segments_;
  SensorNoise noise_;
  std::vector<Eigen::Quaterniond> q_segment_sensor_;
  std::vector<double> drift_rate_rad_per_s_;
  Eigen::Quaterniond q_world_sensors_;
  double heading_rad_ = 0.0;
  std::mt19937_64 rng_;
};

}  // namespace fabrik
