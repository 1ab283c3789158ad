#include "sensor_targets.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace fabrik {

namespace {
// Quaternions reaching the tracker straight from a file or a caller (the
// decoder checks the configured tolerance and normalises before this).
constexpr double kUnitTolerance = 0.01;
}  // namespace

Eigen::Quaterniond sensors_to_world(const Eigen::Vector3d& rotation_xyz_rad,
                                    const Eigen::Vector3d& up, double heading_rad) {
  const Eigen::Quaterniond axes = Eigen::AngleAxisd(rotation_xyz_rad.z(), Eigen::Vector3d::UnitZ()) *
                                  Eigen::AngleAxisd(rotation_xyz_rad.y(), Eigen::Vector3d::UnitY()) *
                                  Eigen::AngleAxisd(rotation_xyz_rad.x(), Eigen::Vector3d::UnitX());
  return (Eigen::AngleAxisd(heading_rad, up.normalized()) * axes).normalized();
}

bool usable_quaternion(const Eigen::Quaterniond& q, double tolerance) {
  if (!q.coeffs().allFinite()) return false;
  return std::abs(q.norm() - 1.0) <= tolerance;
}

SensorTargets::SensorTargets(const SensorSetup& setup, const Model& model)
    : sensors_(setup.sensors), q_world_sensors_(setup.q_world_sensors) {
  if (!q_world_sensors_.coeffs().allFinite() || q_world_sensors_.norm() < 0.5)
    throw std::invalid_argument("sensors: the sensors' world rotation is not a rotation");
  q_world_sensors_.normalize();
  for (SensorTarget& s : sensors_) {
    if (s.segment < 0 || s.segment >= static_cast<int>(model.segments.size()))
      throw std::invalid_argument("sensor '" + s.sensor + "': no such segment in the model");
    if (!(s.weight > 0.0) || !std::isfinite(s.weight))
      throw std::invalid_argument("sensor '" + s.sensor + "': weight must be positive and finite");
    if (!s.q_segment_sensor.coeffs().allFinite() || s.q_segment_sensor.norm() < 0.5)
      throw std::invalid_argument("sensor '" + s.sensor + "': its rotation is not a rotation");
    s.q_segment_sensor.normalize();
    q_sensor_segment_.push_back(s.q_segment_sensor.conjugate());
  }
  const std::size_t n = sensors_.size();
  q_world_segment_.assign(n, Eigen::Quaterniond::Identity());
  visible_.assign(n, 0);
  occluded_.assign(n, 1);
  error_rad_.assign(n, std::numeric_limits<double>::quiet_NaN());
  occluded_count_ = static_cast<int>(n);
}

std::vector<OrientationTarget> SensorTargets::solver_targets() const {
  std::vector<OrientationTarget> out;
  for (const SensorTarget& s : sensors_) out.push_back({s.segment, s.level, s.weight});
  return out;
}

bool SensorTargets::set_measured(std::span<const Eigen::Quaterniond> q_sensors_sensor,
                                 std::span<const std::uint8_t> visible) {
  const std::size_t n = sensors_.size();
  const bool none = q_sensors_sensor.empty() && visible.empty();
  if (!none && (q_sensors_sensor.size() != n || visible.size() != n)) return false;
  occluded_count_ = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const bool seen =
        !none && visible[k] != 0 && usable_quaternion(q_sensors_sensor[k], kUnitTolerance);
    visible_[k] = seen ? 1 : 0;
    occluded_[k] = seen ? 0 : 1;
    if (!seen) {
      ++occluded_count_;
      continue;
    }
    q_world_segment_[k] =
        (q_world_sensors_ * q_sensors_sensor[k].normalized() * q_sensor_segment_[k]).normalized();
  }
  return true;
}

void SensorTargets::measure(const Posture& posture) {
  double sum_sq = 0.0;
  int count = 0;
  max_rad_ = 0.0;
  worst_ = -1;
  for (std::size_t k = 0; k < sensors_.size(); ++k) {
    if (!visible_[k]) {
      error_rad_[k] = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    const double e = posture.segments[sensors_[k].segment].q_world.angularDistance(q_world_segment_[k]);
    error_rad_[k] = e;
    sum_sq += e * e;
    ++count;
    if (worst_ < 0 || e > max_rad_) max_rad_ = e, worst_ = static_cast<int>(k);
  }
  rms_rad_ = count > 0 ? std::sqrt(sum_sq / count) : 0.0;
}

}  // namespace fabrik
