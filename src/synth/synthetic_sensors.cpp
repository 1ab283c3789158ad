#include "synthetic_sensors.hpp"
#include "random_draws.hpp"

#include <numbers>

namespace fabrik {

namespace {
Eigen::Quaterniond random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return draw_rotation(g, rng);
}

Eigen::Quaterniond small_rotation(const Eigen::Vector3d& v_rad) {
  const double angle = v_rad.norm();
  if (angle < 1e-15) return Eigen::Quaterniond::Identity();
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, v_rad / angle));
}
}  // namespace

SyntheticSensors::SyntheticSensors(std::vector<int> segments, SensorNoise noise, unsigned seed)
    : segments_(std::move(segments)), noise_(noise), rng_(seed) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (std::size_t k = 0; k < segments_.size(); ++k) {
    q_segment_sensor_.push_back(random_rotation(rng_));
    drift_rate_rad_per_s_.push_back(unit(rng_) * noise_.drift_rad_per_s);
  }
  heading_rad_ = unit(rng_) * std::numbers::pi;
  // A z-up sensors' world: -90 deg about x takes its z onto the model's y.
  q_world_sensors_ = Eigen::AngleAxisd(heading_rad_, Eigen::Vector3d::UnitY()) *
                     Eigen::AngleAxisd(-std::numbers::pi / 2, Eigen::Vector3d::UnitX());
}

void SyntheticSensors::sample(const Posture& posture, double t_s,
                              std::span<Eigen::Quaterniond> out) {
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Quaterniond q_sensors_world = q_world_sensors_.conjugate();
  for (std::size_t k = 0; k < segments_.size(); ++k) {
    const Eigen::Quaterniond drift(
        Eigen::AngleAxisd(drift_rate_rad_per_s_[k] * t_s, Eigen::Vector3d::UnitZ()));
    const Eigen::Quaterniond jitter = small_rotation(draw_vector3(g, rng_) * noise_.noise_rad);
    out[k] = (drift * q_sensors_world * posture.segments[segments_[k]].q_world *
              q_segment_sensor_[k] * jitter)
                 .normalized();
  }
}

}  // namespace fabrik
