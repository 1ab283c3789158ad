#include "tracker_core.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "common/format_number.hpp"
#include "solver/joint_angles.hpp"
#include "tracking/settings_bounds.hpp"

namespace fabrik {

namespace {

bool hold_enabled(const TrackerSetup& s) {
  return s.occlusion.hold_s > 0.0;
}

// The solver's targets: one per marker, then (if holding is on) one more per
// marker at the hold level, which pulls towards the last measured position.
std::vector<Target> solver_targets(const TrackerSetup& s) {
  if (!s.model) throw std::invalid_argument("tracker: no model");
  std::vector<Target> targets;
  for (const MarkerTarget& m : s.markers) {
    if (m.point < 0 || m.point >= static_cast<int>(s.model->points.size()))
      throw std::invalid_argument("tracker: marker '" + m.marker + "' has no model point");
    targets.push_back({m.point, m.level, m.weight});
  }
  if (hold_enabled(s))
    for (const MarkerTarget& m : s.markers)
      targets.push_back({m.point, s.occlusion.hold_level, m.weight});
  return targets;
}

std::vector<int> marker_points(const TrackerSetup& s) {
  std::vector<int> points;
  for (const MarkerTarget& m : s.markers) points.push_back(m.point);
  return points;
}

bool finite(const Eigen::Vector3d& p) {
  return p.allFinite();
}

// The model point of every marker, checked (the predictor is built before the solver).
std::vector<int> checked_marker_points(const TrackerSetup& s) {
  solver_targets(s);
  return marker_points(s);
}

// The solver's orientation targets: the sensors', then the gap predictor's.
std::vector<OrientationTarget> orientation_targets(const SensorTargets& sensors,
                                                  const GapPredictor& predictor) {
  std::vector<OrientationTarget> all = sensors.solver_targets();
  all.insert(all.end(), predictor.orientation_targets().begin(),
             predictor.orientation_targets().end());
  return all;
}

// The left/right pairs of the mirror rule: the setup's, else those the names give.
std::vector<std::array<int, 2>> mirror_pairs(const TrackerSetup& s) {
  const int n = static_cast<int>(s.markers.size());
  for (const auto& [r, l] : s.mirror_pairs)
    if (r < 0 || r >= n || l < 0 || l >= n || r == l)
      throw std::invalid_argument("tracker: a mirror pair names no marker, or one twice");
  if (const int m = marker_in_two_pairs(s.mirror_pairs); m >= 0)
    throw std::invalid_argument("tracker: marker '" +
                                s.markers[static_cast<std::size_t>(m)].marker +
                                "' is in two mirror pairs");
  if (!s.mirror_pairs.empty()) return s.mirror_pairs;
  std::vector<std::string> names;
  for (const MarkerTarget& m : s.markers) names.push_back(m.marker);
  return mirror_pairs_from_names(names);
}

// A setting's value in a message: -1e-07, not to_string's -0.000000.
std::string number_text(double v) {
  return format_number("%g", v);
}

// Why the setup's settings cannot run (a NaN bar, a negative time, a count or cutoff below its
// least, a fraction above 1: settings_bounds.hpp, the config reader's bounds too), or "".
std::string settings_problem(const TrackerSetup& s) {
  namespace b = settings_bounds;
  if (std::string why = solver_options_problem(s.solver); !why.empty()) return "solver: " + why;
  const OutlierSettings& o = s.outliers;
  const PredictionSettings& p = s.prediction;
  constexpr double kAny = INFINITY;
  struct Amount {
    const char* name;
    double value, least, most;
  };
  const Amount amounts[] = {
      {"occlusion.hold_s", s.occlusion.hold_s, 0.0, kAny},
      {"outliers.floor_m", o.floor_m, b::kLeastOutlierFloorM, kAny},
      {"outliers.median_factor", o.median_factor, b::kLeastMedianFactor, kAny},
      {"outliers.moved_m", o.moved_m, 0.0, kAny},
      {"outliers.mirror_ratio", o.mirror_ratio, 0.0, b::kMostFraction},
      {"outliers.mirror_floor_m", o.mirror_floor_m, 0.0, kAny},
      {"outliers.mirror_max_s", o.mirror_max_s, 0.0, kAny},
      {"confidence.threshold", s.confidence.threshold, 0.0, b::kMostFraction},
      {"smoothing.min_cutoff_hz", s.smoothing.min_cutoff_hz, b::kLeastCutoffHz, kAny},
      {"smoothing.beta_per_m", s.smoothing.beta_per_m, 0.0, kAny},
      {"smoothing.d_cutoff_hz", s.smoothing.d_cutoff_hz, b::kLeastCutoffHz, kAny},
      {"quality.rms_m", s.quality.rms_m, 0.0, kAny},
      {"quality.max_m", s.quality.max_m, 0.0, kAny},
      {"cold_start.after_gap_s", s.cold_start.after_gap_s, 0.0, kAny},
      {"prediction.weight", p.weight, 0.0, kAny},
      {"prediction.velocity_decay_s", p.velocity_decay_s, 0.0, kAny},
      {"prediction.velocity_window_s", p.velocity_window_s, 0.0, kAny},
      {"prediction.return_speed_m_per_s", p.return_speed_m_per_s, 0.0, kAny},
      {"prediction.donor_min_sine", p.donor_min_sine, 0.0, kAny},
      {"prediction.donor_score_floor_m", p.donor_score_floor_m, 0.0, kAny},
      {"prediction.donor_gate", p.donor_gate, 0.0, kAny}};
  for (const Amount& a : amounts)
    if (!std::isfinite(a.value) || a.value < a.least || a.value > a.most)
      return std::string(a.name) + " must be a finite number from " + number_text(a.least) +
             (a.most == kAny ? " up" : " to " + number_text(a.most)) + " (is " +
             number_text(a.value) + ")";
  const std::pair<const char*, int> counts[] = {
      {"outliers.max_per_frame", o.max_per_frame},
      {"prediction.donor_candidates", p.donor_candidates},
      {"prediction.donor_triples", p.donor_triples},
      {"prediction.donor_choices_per_frame", p.donor_choices_per_frame},
      {"prediction.donor_max_joints", p.donor_max_joints}};
  for (const auto& [name, value] : counts)
    if (value < 0)
      return std::string(name) + " must not be negative (is " + std::to_string(value) + ")";
  if (o.min_markers < b::kLeastOutlierMarkers)
    return "outliers.min_markers must be at least " + std::to_string(b::kLeastOutlierMarkers) +
           " (is " + std::to_string(o.min_markers) + ")";
  if (s.cold_start.max_iterations < b::kLeastColdIterations)
    return "cold_start.max_iterations must be at least " + std::to_string(b::kLeastColdIterations) +
           " (is " + std::to_string(s.cold_start.max_iterations) + ")";
  return {};
}

// The setup, refused at once where it cannot run: no model, or settings no frame can use.
TrackerSetup checked_setup(TrackerSetup s) {
  if (!s.model) throw std::invalid_argument("tracker: no model");
  if (const std::string why = settings_problem(s); !why.empty())
    throw std::invalid_argument("tracker: " + why);
  return s;
}

}  // namespace

TrackerCore::TrackerCore(TrackerSetup setup)
    : setup_(checked_setup(std::move(setup))),
      sensors_(setup_.sensors, *setup_.model),
      predictor_(*setup_.model, checked_marker_points(setup_), setup_.prediction),
      solver_(setup_.model, solver_targets(setup_), setup_.solver,
              orientation_targets(sensors_, predictor_)),
      rest_(Posture::rest(*setup_.model)),
      posture_(rest_),
      cold_options_(cold_solver_options(setup_.solver, setup_.cold_start)),
      outliers_(*setup_.model, setup_.outliers, marker_points(setup_)),
      start_(rest_),
      warm_start_(*setup_.model),
      n_(static_cast<int>(setup_.markers.size())),
      mirror_(setup_.outliers, mirror_pairs(setup_)),
      smoother_(setup_.smoothing, n_),
      branch_(*setup_.model) {
  const int n_targets = static_cast<int>(solver_.targets().size());
  weight_scale_.assign(n_targets, 1.0);
  input_m_.assign(n_, Eigen::Vector3d::Zero());
  predicted_m_.assign(n_, Eigen::Vector3d::Zero());
  target_world_m_.assign(n_targets, Eigen::Vector3d::Zero());
  target_visible_.assign(n_targets, 0);
  last_seen_m_.assign(n_, Eigen::Vector3d::Zero());
  last_seen_s_.assign(n_, -INFINITY);
  joints_m_.assign(model().joints.size(), Eigen::Vector3d::Zero());
  markers_m_.assign(n_, Eigen::Vector3d::Zero());
  occluded_.assign(n_, 1);
  held_.assign(n_, 0);
  result_.joints_world_m = joints_m_;
  result_.markers_world_m = markers_m_;
  result_.occluded = occluded_;
  result_.held = held_;
  orient_q_world_.assign(solver_.orientations().size(), Eigen::Quaterniond::Identity());
  orient_visible_.assign(solver_.orientations().size(), 0);
  gap_s_.assign(n_, 0.0);
  last_measured_s_.assign(n_, -INFINITY);
  measured_.assign(n_, 0);
  result_.gap_s = gap_s_;
  coordinates_.assign(model().coordinates.size(), 0.0);
  coordinates_now_.assign(model().coordinates.size(), 0.0);
  segment_q_.assign(model().segments.size(), Eigen::Quaterniond::Identity());
  segment_origin_m_.assign(model().segments.size(), Eigen::Vector3d::Zero());
  result_.coordinates = coordinates_;
  result_.segment_q_world = segment_q_;
  result_.segment_origin_world_m = segment_origin_m_;
  result_.sensor_occluded = sensors_.occluded();
  result_.sensor_error_rad = sensors_.error_rad();
  marker_points_ = marker_points(setup_);
  outlier_.assign(n_, 0);
  relabelled_from_.assign(n_, -1);
  result_.relabelled_from = relabelled_from_;
  beyond_.assign(n_, 0);
  marker_residual_m_.assign(n_, NAN);
  result_.outliers = outlier_;
  result_.beyond = beyond_;
  result_.marker_residual_m = marker_residual_m_;
}

void TrackerCore::reset() {
  posture_ = rest_;
  warm_ = false;
  coordinates_continue_ = false;
  warm_start_.reset();
  std::fill(last_seen_s_.begin(), last_seen_s_.end(), -INFINITY);
  std::fill(last_measured_s_.begin(), last_measured_s_.end(), -INFINITY);
  clock_start_s_ = last_time_s_ = NAN;
  predictor_.reset();
  smoother_.reset();
  mirror_.reset();
}

void TrackerCore::clear_verdict() {
  TrackResult& r = result_;
  r.solve = SolveResult{};
  r.solve_us = 0.0;
  r.occluded_count = r.low_confidence_count = r.mirrored_count = 0;
  r.residual_rms_m = r.residual_max_m = 0.0;
  r.residual_count = 0;
  r.worst_marker = -1;
  r.sensor_occluded_count = 0;
  r.sensor_rms_rad = r.sensor_max_rad = 0.0;
  r.worst_sensor = -1;
  r.root_held = false;
  r.outlier_count = 0;
  r.quality = FitQuality::none;
  r.beyond_count = 0;
  r.cold_start = false;
}

const TrackResult& TrackerCore::track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                                  std::span<const std::uint8_t> visible) {
  return track(time_s, measured_world_m, visible, {}, {});
}

const TrackResult& TrackerCore::track(double time_s, std::span<const Eigen::Vector3d> measured_world_m,
                                  std::span<const std::uint8_t> visible,
                                  std::span<const Eigen::Quaterniond> q_sensors_sensor,
                                  std::span<const std::uint8_t> sensor_visible,
                                  std::span<const float> confidence) {
  if (static_cast<int>(measured_world_m.size()) != n_ || static_cast<int>(visible.size()) != n_ ||
      (!confidence.empty() && static_cast<int>(confidence.size()) != n_) ||
      !sensors_.set_measured(q_sensors_sensor, sensor_visible)) {
    clear_verdict();
    result_.solve.status = SolveStatus::size_mismatch;
    return result_;
  }
  // A NaN time would read as a long gap (a cold start, every gap's age restarted): refused,
  // the state kept, as the solver refuses a non-finite target.
  if (!std::isfinite(time_s)) {
    clear_verdict();
    result_.solve.status = SolveStatus::non_finite_input;
    return result_;
  }
  if (!(time_s >= last_time_s_)) {  // the first frame, or the clock went back
    clock_start_s_ = time_s;
    std::fill(last_measured_s_.begin(), last_measured_s_.end(), -INFINITY);
  }
  last_time_s_ = time_s;
  const bool hold = hold_enabled(setup_);
  int occluded_count = 0, low_confidence = 0;
  const ConfidenceSettings& cs = setup_.confidence;
  for (int i = 0; i < n_; ++i) {
    bool seen = visible[i] != 0 && finite(measured_world_m[i]);
    if (!confidence.empty()) {
      // A NaN confidence is no confidence: occluded.
      const double c = confidence[i];
      const bool trusted = c >= cs.threshold;
      low_confidence += seen && !trusted;
      seen = seen && trusted;
      weight_scale_[i] = cs.scale_weight && trusted ? std::min(c, 1.0) : 1.0;
    } else {
      weight_scale_[i] = 1.0;
    }
    occluded_[i] = seen ? 0 : 1;
    measured_[i] = seen ? 1 : 0;
    target_visible_[i] = seen ? 1 : 0;
    outlier_[i] = 0;
    relabelled_from_[i] = -1;
    if (seen) {
      target_world_m_[i] = measured_world_m[i];
    } else {
      ++occluded_count;
    }
    held_[i] = 0;
    if (hold) {
      // Time may restart with the source: a clock that went backwards ends holding.
      const double age_s = time_s - last_seen_s_[i];
      held_[i] = !seen && age_s >= 0.0 && age_s <= setup_.occlusion.hold_s ? 1 : 0;
      target_visible_[n_ + i] = held_[i];
      target_world_m_[n_ + i] = last_seen_m_[i];
    }
  }
  const bool any_point = std::find(target_visible_.begin(), target_visible_.end(), 1) !=
                         target_visible_.end();
  // A long gap (either way: a source may restart its clock) makes the last pose stale.
  const double gap_s = time_s - last_solved_s_;
  const bool cold = !warm_ || !(std::abs(gap_s) <= setup_.cold_start.after_gap_s);
  // A clock that went back is a new recording: its coordinates start afresh.
  // After a gap the subject is the same, so they stay continuous across it.
  if (!warm_ || gap_s < 0.0) coordinates_continue_ = false;
  if (cold) {
    predictor_.reset();
    mirror_.reset();
  }
  result_.mirrored_count = 0;
  if (!cold) {
    start_ = posture_;
    // The motion carried on, where markers place the root (warm_start.hpp).
    warm_start_.predict(time_s, any_point, start_);
    if (setup_.outliers.enabled && setup_.outliers.relabel_mirrored) {
      for (const auto& pair : mirror_.pairs())
        for (const int i : pair)
          predicted_m_[i] = start_.point_world_m(model(), marker_points_[i]);
      result_.mirrored_count = mirror_.apply(time_s, std::span(target_world_m_).first(n_),
                                             measured_, predicted_m_, relabelled_from_);
    }
  }
  std::copy(target_world_m_.begin(), target_world_m_.begin() + n_, input_m_.begin());
  if (setup_.smoothing.enabled) {
    if (cold) smoother_.reset();
    for (int i = 0; i < n_; ++i) {
      if (measured_[i])
        target_world_m_[i] = smoother_.filter(i, time_s, target_world_m_[i]);
      else
        smoother_.forget(i);
    }
  }
  solver_.set_weight_scale(weight_scale_);
  // The solver's orientation targets: the sensors' as measured, then the predictor's.
  const std::size_t n_sensors = sensors_.visible().size();
  std::copy(sensors_.q_world_segment().begin(), sensors_.q_world_segment().end(),
            orient_q_world_.begin());
  std::copy(sensors_.visible().begin(), sensors_.visible().end(), orient_visible_.begin());
  predictor_.before_solve(time_s, measured_,
                          std::span(target_world_m_).first(n_),
                          std::span(orient_q_world_).subspan(n_sensors),
                          std::span(orient_visible_).subspan(n_sensors));
  // Nothing to solve for: a cold start would hand back the rest posture (a jump to a pose no
  // one held, mid-gap); the last pose is held instead, as before the cold-start gap.
  const bool any_target = any_point || std::find(orient_visible_.begin(), orient_visible_.end(),
                                                 1) != orient_visible_.end();
  const auto t0 = std::chrono::steady_clock::now();
  if (cold && !any_target) {
    start_ = posture_;  // same size: copies without allocating
  } else if (cold) {
    start_ = rest_;
    if (setup_.cold_start.align)
      align_rigidly(model(), marker_points_, target_world_m_,
                    std::span<const std::uint8_t>(target_visible_).first(n_), start_);
    solver_.set_options(cold_options_);
  }
  const Eigen::Vector3d root_before_m = start_.segments[0].base_world_m;
  result_.solve = outliers_.solve(solver_, model(), target_world_m_, target_visible_,
                                  orient_q_world_, orient_visible_, start_, posture_,
                                  outlier_, relabelled_from_);
  predictor_.place_leaves(posture_);
  if (cold) solver_.set_options(setup_.solver);
  const auto t1 = std::chrono::steady_clock::now();
  result_.solve_us = std::chrono::duration<double, std::micro>(t1 - t0).count();
  result_.cold_start = cold && any_target;  // a held pose did not start cold
  if (result_.solve.status != SolveStatus::no_targets) {
    warm_ = true;
    last_solved_s_ = time_s;
  }
  // Rotations say nothing about where the body is: without a marker, the
  // chain may have dragged the root while the segments turned. Moving the
  // whole posture back changes no rotation and no joint connection.
  result_.root_held = !any_point && result_.solve.status != SolveStatus::no_targets;
  if (result_.root_held) {
    const Eigen::Vector3d shift_m = root_before_m - posture_.segments[0].base_world_m;
    for (SegmentPose& pose : posture_.segments) pose.base_world_m += shift_m;
  }
  if (cold) warm_start_.reset();
  if (result_.solve.status != SolveStatus::no_targets)
    warm_start_.record(time_s, posture_, !result_.root_held);
  for (int i = 0; i < n_; ++i) {
    if (occluded_[i] || !target_visible_[i]) continue;  // outliers left out are not held
    last_seen_m_[i] = target_world_m_[i];
    last_seen_s_[i] = time_s;
  }

  for (std::size_t j = 0; j < joints_m_.size(); ++j)
    joints_m_[j] = posture_.point_world_m(model(), model().joints[j].point);
  double sq_m2 = 0.0, max_m = 0.0;
  int count = 0, worst = -1, outlier_count = 0;
  for (int i = 0; i < n_; ++i) {
    markers_m_[i] = posture_.point_world_m(model(), setup_.markers[i].point);
    marker_residual_m_[i] = NAN;
    if (occluded_[i]) continue;
    const double d_m = (markers_m_[i] - target_world_m_[i]).norm();
    marker_residual_m_[i] = d_m;
    outlier_count += outlier_[i];
    if (!target_visible_[i]) continue;  // an outlier left out
    sq_m2 += d_m * d_m;
    ++count;
    if (worst < 0 || d_m > max_m) max_m = d_m, worst = i;
  }
  predictor_.after_solve(time_s, posture_, measured_, input_m_, markers_m_, gap_s_);
  for (int i = 0; i < n_; ++i) {
    if (measured_[i]) last_measured_s_[i] = time_s;
    gap_s_[i] = measured_[i] ? 0.0 : time_s - std::max(last_measured_s_[i], clock_start_s_);
  }
  // A sample the frame rejected (an outlier, or relabelled by the outlier rule) does not enter
  // the filter: it holds its state as if the sample had not come.
  if (setup_.smoothing.enabled)
    for (int i = 0; i < n_; ++i)
      if (measured_[i] && !outlier_[i]) smoother_.commit(i);
  result_.occluded_count = occluded_count;
  result_.low_confidence_count = low_confidence;
  result_.outlier_count = outlier_count;
  result_.residual_count = count;
  result_.residual_rms_m = count > 0 ? std::sqrt(sq_m2 / count) : 0.0;
  result_.residual_max_m = max_m;
  result_.worst_marker = worst;
  sensors_.measure(posture_);
  result_.sensor_occluded_count = sensors_.occluded_count();
  result_.sensor_rms_rad = sensors_.rms_rad();
  result_.sensor_max_rad = sensors_.max_rad();
  result_.worst_sensor = sensors_.worst();
  result_.quality = judge_fit(setup_.quality, count, result_.residual_rms_m, max_m);
  int beyond_count = 0;
  for (int i = 0; i < n_; ++i) {
    beyond_[i] = !occluded_[i] && target_visible_[i] && marker_residual_m_[i] > setup_.quality.max_m;
    beyond_count += beyond_[i];
  }
  result_.beyond_count = beyond_count;
  coordinate_values(model(), posture_, coordinates_now_);
  branch_.follow(time_s, coordinates_now_, coordinates_continue_);
  std::copy(coordinates_now_.begin(), coordinates_now_.end(), coordinates_.begin());
  coordinates_continue_ = true;
  for (std::size_t s = 0; s < segment_q_.size(); ++s) {
    const SegmentPose& pose = posture_.segments[s];
    segment_q_[s] = pose.q_world * model().segments[s].q_anatomical;
    segment_origin_m_[s] = pose.base_world_m;
  }
  return result_;
}

}  // namespace fabrik
