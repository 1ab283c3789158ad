#include "tracker.hpp"

#include "tracker_core.hpp"

namespace fabrik {

namespace {
// What a moved-from Tracker's track() gives: no frame, as a moved-from SolverWorkspace's solve.
const TrackResult& moved_from() {
  static const TrackResult result = [] {
    TrackResult r;
    r.solve.status = SolveStatus::wrong_workspace;
    return r;
  }();
  return result;
}
}  // namespace

Tracker::Tracker(TrackerSetup setup) : core_(std::make_unique<TrackerCore>(std::move(setup))) {}
Tracker::~Tracker() = default;
Tracker::Tracker(Tracker&&) noexcept = default;
Tracker& Tracker::operator=(Tracker&&) noexcept = default;

const TrackerSetup& Tracker::setup() const { return core_->setup(); }
const Model& Tracker::model() const { return core_->model(); }
int Tracker::marker_count() const {
  return core_ ? core_->marker_count() : 0;
}
int Tracker::sensor_count() const {
  return core_ ? core_->sensor_count() : 0;
}

const TrackResult& Tracker::track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                                  std::span<const std::uint8_t> visible) {
  if (!core_) return moved_from();
  return core_->track(time_s, measured_world_m, visible);
}

const TrackResult& Tracker::track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                                  std::span<const std::uint8_t> visible,
                                  std::span<const Eigen::Quaterniond> q_sensors_sensor,
                                  std::span<const std::uint8_t> sensor_visible) {
  if (!core_) return moved_from();
  return core_->track(time_s, measured_world_m, visible, q_sensors_sensor, sensor_visible);
}

const TrackResult& Tracker::track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                                  std::span<const std::uint8_t> visible,
                                  std::span<const Eigen::Quaterniond> q_sensors_sensor,
                                  std::span<const std::uint8_t> sensor_visible,
                                  std::span<const float> confidence) {
  if (!core_) return moved_from();
  return core_->track(time_s, measured_world_m, visible, q_sensors_sensor, sensor_visible,
                      confidence);
}

const TrackResult& Tracker::track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                                  std::span<const std::uint8_t> visible,
                                  std::span<const float> confidence) {
  if (!core_) return moved_from();
  return core_->track(time_s, measured_world_m, visible, {}, {}, confidence);
}

void Tracker::reset() {
  if (core_) core_->reset();
}
const Posture& Tracker::posture() const { return core_->posture(); }

}  // namespace fabrik
