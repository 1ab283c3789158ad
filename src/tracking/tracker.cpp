#include "tracker.hpp"

#include "tracker_core.hpp"

namespace fabrik {

Tracker::Tracker(TrackerSetup setup) : core_(std::make_unique<TrackerCore>(std::move(setup))) {}
Tracker::~Tracker() = default;
Tracker::Tracker(Tracker&&) noexcept = default;
Tracker& Tracker::operator=(Tracker&&) noexcept = default;

const TrackerSetup& Tracker::setup() const { return core_->setup(); }
const Model& Tracker::model() const { return core_->model(); }
int Tracker::marker_count() const { return core_->marker_count(); }
int Tracker::sensor_count() const { return core_->sensor_count(); }

const TrackResult& Tracker::track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                                  std::span<const std::uint8_t> visible) {
  return core_->track(time_s, measured_world_m, visible);
}

const TrackResult& Tracker::track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                                  std::span<const std::uint8_t> visible,
                                  std::span<const Eigen::Quaterniond> q_sensors_sensor,
                                  std::span<const std::uint8_t> sensor_visible) {
  return core_->track(time_s, measured_world_m, visible, q_sensors_sensor, sensor_visible);
}

const TrackResult& Tracker::track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                                  std::span<const std::uint8_t> visible,
                                  std::span<const Eigen::Quaterniond> q_sensors_sensor,
                                  std::span<const std::uint8_t> sensor_visible,
                                  std::span<const float> confidence) {
  return core_->track(time_s, measured_world_m, visible, q_sensors_sensor, sensor_visible,
                      confidence);
}

const TrackResult& Tracker::track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                                  std::span<const std::uint8_t> visible,
                                  std::span<const float> confidence) {
  return core_->track(time_s, measured_world_m, visible, {}, {}, confidence);
}

void Tracker::reset() { core_->reset(); }
const Posture& Tracker::posture() const { return core_->posture(); }

}  // namespace fabrik
