#include "live_marker_fill.hpp"

#include <algorithm>
#include <cmath>

#include "rotation_prediction.hpp"
#include "triad.hpp"

namespace fabrik {

namespace {

// Measured frames kept for choosing donors: about a gait cycle at 100 Hz, two
// at 60 Hz, so a donor that only looked stable for a moment is found out.
constexpr int kHistory = 128;
// Of which at most this many, evenly spaced, score a candidate.
constexpr int kScored = 64;

}  // namespace

std::vector<std::uint8_t> nearby_markers(const Model& model, std::span<const int> marker_segments,
                                         int max_joints) {
  // Each segment's neighbourhood: a breadth-first search over the tree's
  // edges that stops max_joints joints out, so setup grows with the segments
  // times their neighbourhoods, not with the cube of the segments.
  const std::size_t n_seg = model.segments.size(), n = marker_segments.size();
  std::vector<std::vector<int>> joined(n_seg);
  for (std::size_t s = 0; s < n_seg; ++s)
    if (const int parent = model.segments[s].parent; parent >= 0) {
      joined[s].push_back(parent);
      joined[static_cast<std::size_t>(parent)].push_back(static_cast<int>(s));
    }
  std::vector<std::vector<int>> markers_on(n_seg);
  for (std::size_t i = 0; i < n; ++i)
    markers_on[static_cast<std::size_t>(marker_segments[i])].push_back(static_cast<int>(i));
  std::vector<std::uint8_t> nearby(n * n, 0);
  if (max_joints < 0) return nearby;
  std::vector<int> distance(n_seg, -1), queue;
  for (std::size_t from = 0; from < n_seg; ++from) {
    if (markers_on[from].empty()) continue;
    queue.assign(1, static_cast<int>(from));
    distance[from] = 0;
    for (std::size_t q = 0; q < queue.size(); ++q) {
      const int s = queue[q];
      if (distance[s] == max_joints) continue;
      for (int t : joined[static_cast<std::size_t>(s)])
        if (distance[t] < 0) distance[t] = distance[s] + 1, queue.push_back(t);
    }
    for (int s : queue) {
      for (int i : markers_on[from])
        for (int m : markers_on[static_cast<std::size_t>(s)])
          if (m != i) nearby[static_cast<std::size_t>(i) * n + static_cast<std::size_t>(m)] = 1;
      distance[s] = -1;
    }
  }
  return nearby;
}

LiveMarkerFill::LiveMarkerFill(const Model& model, std::span<const int> marker_points,
                               const PredictionSettings& settings)
    : settings_(settings), n_(static_cast<int>(marker_points.size())) {
  for (int p : marker_points) {
    const Point& point = model.points[p];
    marker_segment_.push_back(point.segment);
    marker_local_m_.push_back(point.p_local_m);
  }
  history_.resize(kHistory);
  for (Measured& h : history_) {
    h.markers_m.assign(static_cast<std::size_t>(n_), Eigen::Vector3d::Zero());
    h.seen.assign(static_cast<std::size_t>(n_), 0);
    h.segment_local_m.assign(static_cast<std::size_t>(n_), Eigen::Vector3d::Zero());
  }
  nearby_ = nearby_markers(model, marker_segment_, settings_.donor_max_joints);
  settings_.donor_candidates = std::max(0, settings_.donor_candidates);
  settings_.donor_triples = std::max(0, settings_.donor_triples);
  const auto k = static_cast<std::size_t>(settings_.donor_candidates);
  donors_.assign(static_cast<std::size_t>(n_ * settings_.donor_triples), Donors{});
  donor_count_.assign(static_cast<std::size_t>(n_), 0);
  skeleton_score_m_.assign(static_cast<std::size_t>(n_), NAN);
  candidates_.assign(k, -1);
  spread_m_.assign(k, 0.0);
  scored_.assign(k >= 3 ? k * (k - 1) * (k - 2) / 6 : 0, Donors{});  // every triple
  series_m_.assign(kHistory, Eigen::Vector3d::Zero());
  series_ok_.assign(kHistory, 0);
  offset_local_m_.assign(static_cast<std::size_t>(n_), Eigen::Vector3d::Zero());
  has_offset_.assign(static_cast<std::size_t>(n_), 0);
  was_seen_.assign(static_cast<std::size_t>(n_), 0);
  ever_seen_.assign(static_cast<std::size_t>(n_), 0);
  last_seen_s_.assign(static_cast<std::size_t>(n_), 0.0);
  previous_s_.assign(static_cast<std::size_t>(n_), 0.0);
  latest_m_.assign(static_cast<std::size_t>(n_), Eigen::Vector3d::Zero());
  previous_m_.assign(static_cast<std::size_t>(n_), Eigen::Vector3d::Zero());
  has_previous_.assign(static_cast<std::size_t>(n_), 0);
  handover_m_.assign(static_cast<std::size_t>(n_), Eigen::Vector3d::Zero());
  handover_speed_m_per_s_.assign(static_cast<std::size_t>(n_), 0.0);
  handing_over_.assign(static_cast<std::size_t>(n_), 0);
}

void LiveMarkerFill::reset() {
  history_newest_ = -1;
  history_kept_ = 0;
  std::fill(has_offset_.begin(), has_offset_.end(), std::uint8_t{0});
  std::fill(has_previous_.begin(), has_previous_.end(), std::uint8_t{0});
  std::fill(was_seen_.begin(), was_seen_.end(), std::uint8_t{0});
  std::fill(ever_seen_.begin(), ever_seen_.end(), std::uint8_t{0});
  std::fill(handing_over_.begin(), handing_over_.end(), std::uint8_t{0});
  std::fill(donor_count_.begin(), donor_count_.end(), 0);
}

const LiveMarkerFill::Measured* LiveMarkerFill::measured_past(int age) const {
  if (age >= history_kept_) return nullptr;
  return &history_[static_cast<std::size_t>((history_newest_ - age + kHistory) % kHistory)];
}

void LiveMarkerFill::hand_over(double time_s, std::span<const std::uint8_t> seen,
                               const RotationPrediction& rotation,
                               std::span<Eigen::Vector3d> target_world_m) {
  const RotationPrediction::Past* last = rotation.newest();
  const double dt = last ? time_s - last->time_s : 0.0;
  // The hand-over of returning markers.
  for (int i = 0; i < n_; ++i) {
    const int s = marker_segment_[i];
    if (!seen[i]) {
      handing_over_[i] = 0;
      continue;
    }
    if (!was_seen_[i] && last) {
      // Where the model's point of it would be now (its segment moved on at
      // its recent velocity): from there the target goes to the measurement
      // step by step (the first step in this frame), so the pose does not jump. (The reported fill
      // adds the marker's last offset from the model; the solve must not, or the offset at which it
      // was lost would pull the segment at once.)
      handover_m_[i] = rotation.moved_on(s, marker_local_m_[i], dt) - target_world_m[i];
      handing_over_[i] = handover_m_[i].allFinite() ? 1 : 0;
      // The return takes no longer than the gap: a prediction drifts slowly
      // over a long gap, but an offset after a short one means the pose went
      // wrong while the marker was gone (many markers hidden at once), and
      // holding the marker there would keep it wrong.
      const double gap_s = time_s - (ever_seen_[i] ? last_seen_s_[i] : first_time_s_);
      handover_speed_m_per_s_[i] = settings_.return_speed_m_per_s;
      if (gap_s > 0.0)
        handover_speed_m_per_s_[i] =
            std::max(handover_speed_m_per_s_[i], handover_m_[i].norm() / gap_s);
    }
    if (handing_over_[i]) {
      const double norm = handover_m_[i].norm(), step_m = handover_speed_m_per_s_[i] * dt;
      if (norm <= step_m) {
        handing_over_[i] = 0;
      } else {
        handover_m_[i] *= (norm - step_m) / norm;
      }
    }
    if (handing_over_[i]) target_world_m[i] += handover_m_[i];
  }
}

void LiveMarkerFill::after_solve(double time_s, const Posture& posture,
                                 const RotationPrediction& rotation,
                                 std::span<const std::uint8_t> seen,
                                 std::span<const Eigen::Vector3d> measured,
                                 std::span<Eigen::Vector3d> markers_world_m,
                                 std::span<double> gap_s) {
  if (history_kept_ == 0) first_time_s_ = time_s;  // the first frame, or the first since reset
  choices_left_ = settings_.donor_choices_per_frame;
  for (int i = 0; i < n_; ++i) {
    if (seen[i]) {
      gap_s[i] = 0.0;
      previous_m_[i] = latest_m_[i];
      previous_s_[i] = last_seen_s_[i];
      has_previous_[i] = was_seen_[i];
      latest_m_[i] = measured[i];
      last_seen_s_[i] = time_s;
      was_seen_[i] = ever_seen_[i] = 1;
      continue;
    }
    gap_s[i] = time_s - (ever_seen_[i] ? last_seen_s_[i] : first_time_s_);
    const bool gap_starts = was_seen_[i] != 0;
    was_seen_[i] = 0;
    if (!settings_.enabled) continue;
    if (!ever_seen_[i]) {
      // Its segment's measured markers' mean misfit is the best guess of its own.
      Eigen::Vector3d sum_m = Eigen::Vector3d::Zero();
      int count = 0;
      for (int m = 0; m < n_; ++m)
        if (m != i && seen[m] && marker_segment_[m] == marker_segment_[i])
          sum_m += measured[m] - markers_world_m[m], ++count;
      if (count > 0 && sum_m.allFinite()) markers_world_m[i] += sum_m / count;
      continue;
    }
    const int s = marker_segment_[i];
    const SegmentPose& pose = posture.segments[s];
    // No marker of its own holds the segment: carry the marker on the
    // predicted rotation relative to the (solved) parent instead.
    const Eigen::Quaterniond q = rotation.carrying_rotation(posture, s);
    if (gap_starts) {
      // Where the marker would be now, moving on at its last measured
      // velocity: the prediction starts there, so nothing jumps when it is lost.
      Eigen::Vector3d expected_m = latest_m_[i];
      const double span_s = last_seen_s_[i] - previous_s_[i];
      if (has_previous_[i] && span_s > 0.0)
        expected_m += (latest_m_[i] - previous_m_[i]) * ((time_s - last_seen_s_[i]) / span_s);
      offset_local_m_[i] = q.conjugate() * (expected_m - pose.base_world_m) - marker_local_m_[i];
      has_offset_[i] = offset_local_m_[i].allFinite() ? 1 : 0;
    }
    if (has_offset_[i]) markers_world_m[i] = pose.base_world_m + q * (marker_local_m_[i] + offset_local_m_[i]);
    if (gap_starts) {
      donor_count_[i] = 0;
      if (settings_.donors && choices_left_ > 0) {
        --choices_left_;
        choose_donors(i, seen, measured);
      }
    }
    // The kept triples whose donors are measured now, averaged by weight with
    // the skeleton where it competes; a triple that strays from the skeleton
    // far beyond both scores loses its weight smoothly.
    const Eigen::Vector3d skeleton_m = markers_world_m[i];
    const double floor_sq = settings_.donor_score_floor_m * settings_.donor_score_floor_m;
    const double skeleton_sq = std::max(skeleton_score_m_[i] * skeleton_score_m_[i], floor_sq);
    const bool with_skeleton = std::isfinite(skeleton_score_m_[i]);
    Eigen::Vector3d sum_m = Eigen::Vector3d::Zero();
    double weight_sum = 0.0;
    if (with_skeleton && donor_count_[i] > 0) {
      sum_m = skeleton_m / skeleton_sq;
      weight_sum = 1.0 / skeleton_sq;
    }
    for (int t = 0; t < donor_count_[i]; ++t) {
      const Donors& d = donors_[static_cast<std::size_t>(i * settings_.donor_triples + t)];
      Eigen::Matrix3d r;
      if (!seen[d.a] || !seen[d.b] || !seen[d.c] ||
          !triad(measured[d.a], measured[d.b], measured[d.c], settings_.donor_min_sine, r))
        continue;
      const Eigen::Vector3d p_m = measured[d.a] + r * d.local_m;
      double w = d.weight;
      if (with_skeleton) {
        const double k = settings_.donor_gate;
        const double var = k * k * (1.0 / d.weight + skeleton_sq);
        w *= std::exp(-0.5 * (p_m - skeleton_m).squaredNorm() / var);
      }
      sum_m += w * p_m;
      weight_sum += w;
    }
    if (weight_sum > 0.0 && sum_m.allFinite()) markers_world_m[i] = sum_m / weight_sum;
  }
  history_newest_ = (history_newest_ + 1) % kHistory;
  history_kept_ = std::min(history_kept_ + 1, kHistory);
  Measured& h = history_[static_cast<std::size_t>(history_newest_)];
  for (int i = 0; i < n_; ++i) {
    h.seen[i] = seen[i];
    if (!seen[i]) continue;
    h.markers_m[i] = measured[i];
    const SegmentPose& pose = posture.segments[marker_segment_[i]];
    h.segment_local_m[i] = pose.q_world.conjugate() * (measured[i] - pose.base_world_m);
  }
}

bool LiveMarkerFill::local_in(const Measured& p, int i, const Donors& d, Eigen::Vector3d& local_m) const {
  if (!p.seen[i]) return false;
  if (d.a < 0) {
    local_m = p.segment_local_m[i];
    return local_m.allFinite();
  }
  Eigen::Matrix3d r;
  if (!p.seen[d.a] || !p.seen[d.b] || !p.seen[d.c] ||
      !triad(p.markers_m[d.a], p.markers_m[d.b], p.markers_m[d.c], settings_.donor_min_sine, r))
    return false;
  local_m = r.transpose() * (p.markers_m[i] - p.markers_m[d.a]);
  return local_m.allFinite();
}

double LiveMarkerFill::hold_score(int i, const Donors& d) {
  // Oldest first, ending with the newest frame; at most kScored frames, evenly
  // spaced (the cost of a choice is this times the triples).
  const int step = (history_kept_ + kScored - 1) / kScored;
  const int kept = (history_kept_ + step - 1) / step;
  for (int k = 0; k < kept; ++k)
    series_ok_[k] =
        local_in(*measured_past((kept - 1 - k) * step), i, d, series_m_[k]) ? 1 : 0;
  // Holding from frame s - 1 over the next l frames, wherever all were usable,
  // every quarter of l; l is half the history.
  const int l = std::max(1, kept / 2);
  const int stride = std::max(1, l / 4);
  double sq = 0.0;
  int samples = 0;
  for (int s = 1; s + l <= kept;) {
    bool ok = series_ok_[s - 1] != 0;
    for (int k = s; k < s + l && ok; ++k) ok = series_ok_[k] != 0;
    if (!ok) {
      ++s;
      continue;
    }
    for (int k = s; k < s + l; ++k) sq += (series_m_[k] - series_m_[s - 1]).squaredNorm();
    samples += l;
    s += stride;
  }
  return samples > 0 ? std::sqrt(sq / samples) : NAN;
}

void LiveMarkerFill::choose_donors(int i, std::span<const std::uint8_t> seen,
                                 std::span<const Eigen::Vector3d> measured) {
  const Measured* last = measured_past(0);
  if (!last || !last->seen[i] || history_kept_ < 3) return;
  // Candidates: measured now and when the marker was last seen, ranked by the
  // spread of their distance to it over the recent past.
  const int k_max = settings_.donor_candidates;
  int count = 0;
  for (int m = 0; m < n_; ++m) {
    if (!nearby_[static_cast<std::size_t>(i * n_ + m)] || !seen[m] || !last->seen[m]) continue;
    DistanceSpread distance;
    for (int age = 0; age < history_kept_; ++age) {
      const Measured& p = *measured_past(age);
      if (p.seen[i] && p.seen[m]) distance.add((p.markers_m[m] - p.markers_m[i]).norm());
    }
    if (distance.frames < 3) continue;
    const double spread = distance.spread_m();
    if (!std::isfinite(spread)) continue;
    int at = count;  // insertion into the sorted top k_max
    while (at > 0 && spread_m_[at - 1] > spread) {
      if (at < k_max) candidates_[at] = candidates_[at - 1], spread_m_[at] = spread_m_[at - 1];
      --at;
    }
    if (at < k_max) candidates_[at] = m, spread_m_[at] = spread;
    count = std::min(count + 1, k_max);
  }
  int scored = 0;
  const auto consider = [&](Donors d) {
    if (!local_in(*last, i, d, d.local_m)) return;
    d.score_m = hold_score(i, d);
    if (std::isfinite(d.score_m)) scored_[scored++] = d;
  };
  // The skeleton competes where two more of the segment's markers are
  // measured: with fewer, the marker itself placed its segment in the past
  // and the score would flatter it.
  int holders = 0;
  for (int m = 0; m < n_; ++m)
    holders += m != i && seen[m] && marker_segment_[m] == marker_segment_[i] ? 1 : 0;
  skeleton_score_m_[i] = NAN;
  if (holders >= 2) {
    Donors d;
    if (local_in(*last, i, d, d.local_m)) skeleton_score_m_[i] = hold_score(i, d);
  }
  for (int x = 0; x < count; ++x)
    for (int y = x + 1; y < count; ++y)
      for (int z = y + 1; z < count; ++z)
        consider(Donors{candidates_[x], candidates_[y], candidates_[z]});
  const int keep = std::min(scored, settings_.donor_triples);
  std::partial_sort(scored_.begin(), scored_.begin() + keep, scored_.begin() + scored,
                    [](const Donors& p, const Donors& q) { return p.score_m < q.score_m; });
  int kept = 0;
  for (int t = 0; t < keep; ++t) {
    Donors d = scored_[t];
    // Its coordinates are those at its last measurement (local_m); a triple
    // whose triangle is flat now is not kept.
    Eigen::Matrix3d r;
    if (!triad(measured[d.a], measured[d.b], measured[d.c], settings_.donor_min_sine, r)) continue;
    d.weight = 1.0 / std::pow(std::max(d.score_m, settings_.donor_score_floor_m), 2);
    donors_[static_cast<std::size_t>(i * settings_.donor_triples + kept++)] = d;
  }
  donor_count_[i] = kept;
}

}  // namespace fabrik
