#include "rotation_prediction.hpp"

#include <algorithm>
#include <cmath>

#include "solver/joint_angles.hpp"

namespace fabrik {

namespace {

// Postures kept for velocities: at 60-100 Hz this spans well over the
// velocity window; at higher rates the window shrinks to what it holds.
constexpr int kRing = 32;

// Rotation vector (axis times angle, radians) of a unit quaternion, angle in [0, pi].
Eigen::Vector3d rotation_vector(Eigen::Quaterniond q) {
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  const double n = q.vec().norm();
  if (n < 1e-12) return 2.0 * q.vec();
  return q.vec() * (2.0 * std::atan2(n, q.w()) / n);
}

Eigen::Quaterniond from_rotation_vector(const Eigen::Vector3d& v) {
  const double angle = v.norm();
  if (angle < 1e-12) return Eigen::Quaterniond(1.0, 0.5 * v.x(), 0.5 * v.y(), 0.5 * v.z()).normalized();
  const Eigen::Vector3d axis = v / angle;
  const double s = std::sin(0.5 * angle);
  return {std::cos(0.5 * angle), s * axis.x(), s * axis.y(), s * axis.z()};
}

}  // namespace

RotationPrediction::RotationPrediction(const Model& model, std::span<const int> marker_points,
                                       const PredictionSettings& settings)
    : model_(model), settings_(settings), n_(static_cast<int>(marker_points.size())) {
  const int n_seg = static_cast<int>(model.segments.size());
  target_of_segment_.assign(static_cast<std::size_t>(n_seg), -1);
  for (int p : marker_points) {
    const Point& point = model.points[p];
    marker_segment_.push_back(point.segment);
    if (settings_.enabled && target_of_segment_[point.segment] < 0) {
      target_of_segment_[point.segment] = static_cast<int>(targets_.size());
      targets_.push_back({point.segment, settings_.level, settings_.weight});
    }
  }
  ring_.resize(kRing);
  for (Past& p : ring_) p.posture = Posture::rest(model);
  in_gap_.assign(static_cast<std::size_t>(n_seg), 0);
  gap_start_s_.assign(static_cast<std::size_t>(n_seg), 0.0);
  has_history_.assign(static_cast<std::size_t>(n_seg), 0);
  q_rel_start_.assign(static_cast<std::size_t>(n_seg), Eigen::Quaterniond::Identity());
  omega_rel_.assign(static_cast<std::size_t>(n_seg), Eigen::Vector3d::Zero());
  q_rel_pred_.assign(static_cast<std::size_t>(n_seg), Eigen::Quaterniond::Identity());
  predicted_.assign(static_cast<std::size_t>(n_seg), 0);
  placed_after_.assign(static_cast<std::size_t>(n_seg), 0);
  leaf_.assign(static_cast<std::size_t>(n_seg), 1);
  for (const Segment& seg : model.segments)
    if (seg.parent >= 0) leaf_[static_cast<std::size_t>(seg.parent)] = 0;
  segment_seen_.assign(static_cast<std::size_t>(n_seg), 0);
}

void RotationPrediction::reset() {
  newest_ = -1;
  kept_ = 0;
  started_ = false;
  std::fill(in_gap_.begin(), in_gap_.end(), std::uint8_t{0});
  std::fill(has_history_.begin(), has_history_.end(), std::uint8_t{0});
}

const RotationPrediction::Past* RotationPrediction::past(int age) const {
  if (age >= kept_) return nullptr;
  return &ring_[static_cast<std::size_t>((newest_ - age + kRing) % kRing)];
}

const RotationPrediction::Past* RotationPrediction::velocity_base() const {
  if (kept_ < 2) return nullptr;
  const double newest_s = past(0)->time_s;
  for (int age = 1; age < kept_; ++age)
    if (newest_s - past(age)->time_s >= settings_.velocity_window_s) return past(age);
  return past(kept_ - 1);
}

void RotationPrediction::world_velocity(int s, Eigen::Vector3d& omega, Eigen::Vector3d& v) const {
  omega.setZero();
  v.setZero();
  const Past* base = velocity_base();
  if (!base) return;
  const Past& now = *past(0);
  const double dt = now.time_s - base->time_s;
  if (!(dt > 0.0)) return;
  const SegmentPose& a = base->posture.segments[s];
  const SegmentPose& b = now.posture.segments[s];
  omega = rotation_vector(b.q_world * a.q_world.conjugate()) / dt;
  v = (b.base_world_m - a.base_world_m) / dt;
}

Eigen::Quaterniond RotationPrediction::relative(const Posture& posture, int s) const {
  const int parent = model_.segments[s].parent;
  if (parent < 0) return posture.segments[s].q_world;
  return posture.segments[parent].q_world.conjugate() * posture.segments[s].q_world;
}

void RotationPrediction::start_gap(int s, const Posture& posture) {
  q_rel_start_[s] = relative(posture, s);
  omega_rel_[s].setZero();
  const Past* base = velocity_base();
  if (!base) return;
  const double dt = past(0)->time_s - base->time_s;
  if (!(dt > 0.0)) return;
  omega_rel_[s] = rotation_vector(relative(base->posture, s).conjugate() * q_rel_start_[s]) / dt;
}

bool RotationPrediction::clock_restarted(double time_s) const {
  return started_ && !(time_s >= past(0)->time_s);
}

bool RotationPrediction::before_solve(double time_s, std::span<const std::uint8_t> seen,
                                      std::span<Eigen::Quaterniond> q_world,
                                      std::span<std::uint8_t> q_visible) {
  std::fill(q_visible.begin(), q_visible.end(), std::uint8_t{0});
  std::fill(predicted_.begin(), predicted_.end(), std::uint8_t{0});
  std::fill(placed_after_.begin(), placed_after_.end(), std::uint8_t{0});
  std::fill(segment_seen_.begin(), segment_seen_.end(), std::uint8_t{0});
  for (int i = 0; i < n_; ++i)
    if (seen[i]) segment_seen_[marker_segment_[i]] = 1;
  // Nothing measured at all: no prediction to anchor (the solve reports no_targets).
  if (!settings_.enabled || std::find(seen.begin(), seen.end(), 1) == seen.end()) return false;
  const Past* last = newest();
  const double dt = last ? time_s - last->time_s : 0.0;

  // Segments: which are in a gap now, and their predicted world rotations.
  for (int i = 0; i < n_; ++i)
    if (!seen[i]) in_gap_[marker_segment_[i]] |= 2;
  for (int s = 0; s < static_cast<int>(in_gap_.size()); ++s) {
    if (!(in_gap_[s] & 2)) continue;
    if (!(in_gap_[s] & 1)) {
      gap_start_s_[s] = last ? last->time_s : time_s;
      has_history_[s] = last ? 1 : 0;
      if (last) start_gap(s, last->posture);
    }
    const int k = target_of_segment_[s];
    const int parent = model_.segments[s].parent;
    if (!last || (parent < 0 && !has_history_[s])) continue;
    Eigen::Quaterniond q_rel = Eigen::Quaterniond::Identity();  // rest: no past to go by
    if (has_history_[s]) {
      const double tau = settings_.velocity_decay_s;
      const double g = time_s - gap_start_s_[s];
      const double turn_s = tau > 0.0 ? tau * (1.0 - std::exp(-g / tau)) : 0.0;
      q_rel = q_rel_start_[s] * from_rotation_vector(omega_rel_[s] * turn_s);
    }
    Eigen::Quaterniond q_parent = Eigen::Quaterniond::Identity();
    if (parent >= 0) {
      Eigen::Vector3d omega, v;
      world_velocity(parent, omega, v);
      q_parent = from_rotation_vector(omega * dt) * last->posture.segments[parent].q_world;
    }
    q_rel_pred_[s] = q_rel;
    predicted_[s] = parent >= 0 ? 1 : 0;
    q_world[k] = (q_parent * q_rel).normalized();
    // A leaf without a measured marker: nothing but the prediction would pull
    // it, so it rides on its parent in the solve and is turned once after
    // (place_leaves), the optimum the solver would iterate towards.
    placed_after_[s] = predicted_[s] && !segment_seen_[s] && leaf_[s] ? 1 : 0;
    q_visible[k] = placed_after_[s] ? 0 : 1;
  }
  for (std::size_t s = 0; s < in_gap_.size(); ++s) in_gap_[s] = (in_gap_[s] & 2) ? 1 : 0;
  return true;
}

void RotationPrediction::place_leaves(Posture& posture) const {
  for (int s = 0; s < static_cast<int>(placed_after_.size()); ++s) {
    if (!placed_after_[s]) continue;
    SegmentPose& pose = posture.segments[s];
    const Eigen::Quaterniond previous = pose.q_world;
    pose.set_rotation(posture.segments[model_.segments[s].parent].q_world * q_rel_pred_[s]);
    enforce_joint_limits(model_, s, previous, posture);
  }
}

Eigen::Vector3d RotationPrediction::moved_on(int s, const Eigen::Vector3d& local_m, double dt) const {
  Eigen::Vector3d omega, v;
  world_velocity(s, omega, v);
  const SegmentPose& pose = past(0)->posture.segments[s];
  const Eigen::Quaterniond q = from_rotation_vector(omega * dt) * pose.q_world;
  return pose.base_world_m + v * dt + q * local_m;
}

Eigen::Quaterniond RotationPrediction::carrying_rotation(const Posture& posture, int s) const {
  const bool carry = predicted_[s] && !segment_seen_[s];
  return carry ? posture.segments[model_.segments[s].parent].q_world * q_rel_pred_[s]
               : posture.segments[s].q_world;
}

void RotationPrediction::record(double time_s, const Posture& posture) {
  newest_ = (newest_ + 1) % kRing;
  kept_ = std::min(kept_ + 1, kRing);
  Past& p = ring_[static_cast<std::size_t>(newest_)];
  p.time_s = time_s;
  std::copy(posture.segments.begin(), posture.segments.end(), p.posture.segments.begin());
  started_ = true;
}

}  // namespace fabrik
