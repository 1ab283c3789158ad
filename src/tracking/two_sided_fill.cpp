#include "two_sided_fill.hpp"

#include <algorithm>
#include <cmath>

namespace fabrik {

namespace {

// One tracking pass over the trial in the given order (backward: times
// negated, so the tracker's clock still runs forward): the model's markers,
// and every segment's world frame, per frame.
struct Pass {
  std::vector<Eigen::Vector3d> markers_m;      // [frame * markers + i]
  std::vector<Eigen::Quaterniond> segment_q;   // [frame * segments + s]
  std::vector<Eigen::Vector3d> segment_origin_m;
};

Pass track_pass(const TrackerSetup& setup, std::span<const double> times_s,
                std::span<const Eigen::Vector3d> measured_m, std::span<const std::uint8_t> visible,
                bool backward) {
  Tracker tracker(setup);
  const std::size_t n = setup.markers.size(), frames = times_s.size();
  const std::size_t segments = setup.model->segments.size();
  Pass out;
  out.markers_m.resize(frames * n);
  out.segment_q.resize(frames * segments);
  out.segment_origin_m.resize(frames * segments);
  for (std::size_t k = 0; k < frames; ++k) {
    const std::size_t f = backward ? frames - 1 - k : k;
    const TrackResult& r = tracker.track(backward ? -times_s[f] : times_s[f],
                                         measured_m.subspan(f * n, n), visible.subspan(f * n, n));
    std::copy(r.markers_world_m.begin(), r.markers_world_m.end(), out.markers_m.begin() + f * n);
    std::copy(r.segment_q_world.begin(), r.segment_q_world.end(),
              out.segment_q.begin() + f * segments);
    std::copy(r.segment_origin_world_m.begin(), r.segment_origin_world_m.end(),
              out.segment_origin_m.begin() + f * segments);
  }
  return out;
}

}  // namespace

const char* to_string(FillMethod method) {
  switch (method) {
    case FillMethod::donors:
      return "donors";
    case FillMethod::both:
      return "donors+skeleton";
    case FillMethod::skeleton:
      break;
  }
  return "skeleton";
}

TwoSidedFill fill_two_sided(const TrackerSetup& setup, std::span<const double> times_s,
                            std::span<const Eigen::Vector3d> measured_m,
                            std::span<const std::uint8_t> visible,
                            const DonorFillSettings& donors, bool use_donors) {
  TwoSidedFill fill;
  fill.frames = times_s.size();
  fill.n = setup.markers.size();
  const std::size_t n = fill.n, frames = fill.frames;
  fill.markers_m.assign(frames * n, Eigen::Vector3d::Constant(NAN));
  fill.filled.assign(frames * n, 0);
  bool any_gap = false;
  for (std::size_t k = 0; k < frames * n; ++k) {
    if (visible[k]) fill.markers_m[k] = measured_m[k];
    else any_gap = true;
  }
  if (!any_gap) return fill;
  // Frames before the first measurement of any marker and after the last have nothing to
  // fill from: a fill there would hold one pose for as long as the trial's empty edge.
  std::size_t first_any = frames, last_any = 0;
  for (std::size_t k = 0; k < frames * n; ++k)
    if (visible[k]) first_any = std::min(first_any, k / n), last_any = std::max(last_any, k / n);
  if (first_any == frames) return fill;
  const Pass forward = track_pass(setup, times_s, measured_m, visible, false);
  const Pass backward = track_pass(setup, times_s, measured_m, visible, true);
  const std::size_t segments = setup.model->segments.size();
  std::vector<Eigen::Quaterniond> q(frames);
  std::vector<Eigen::Vector3d> origin_m(frames), skeleton_m, out_m;
  std::vector<int> marker_segments;
  for (const MarkerTarget& m : setup.markers)
    marker_segments.push_back(setup.model->points[m.point].segment);
  const std::vector<std::uint8_t> nearby =
      nearby_markers(*setup.model, marker_segments, setup.prediction.donor_max_joints);
  for (std::size_t i = 0; i < n; ++i) {
    const auto segment = static_cast<std::size_t>(marker_segments[i]);
    bool frames_ready = false;
    std::size_t f = 0;
    while (f < frames) {
      if (visible[f * n + i]) {
        ++f;
        continue;
      }
      const std::size_t gap_first = f;
      while (f < frames && !visible[f * n + i]) ++f;
      const bool before = gap_first > 0, after = f < frames;
      if (!before && !after) continue;  // never measured: nothing to fill from
      const std::size_t first = before ? gap_first : std::max(gap_first, first_any);
      const std::size_t end = after ? f : std::min(f, last_any + 1);
      if (first >= end) continue;
      // The skeleton's fill: the two predictions blended linearly, weight of
      // the backward one 0 at the last sample before the gap, 1 at the first
      // one after it.
      skeleton_m.resize(end - first);
      for (std::size_t g = first; g < end; ++g) {
        const double w =
            !before  ? 1.0
            : !after ? 0.0
                     : static_cast<double>(g - first + 1) / static_cast<double>(end - first + 1);
        const std::size_t k = g * n + i;
        skeleton_m[g - first] = (1.0 - w) * forward.markers_m[k] + w * backward.markers_m[k];
      }
      FilledGap gap{static_cast<int>(i), first, end, FillMethod::skeleton};
      out_m.resize(end - first);
      double donor_share = 0.0;
      if (use_donors && setup.prediction.donors) {
        if (!frames_ready) {
          for (std::size_t h = 0; h < frames; ++h) {
            q[h] = forward.segment_q[h * segments + segment];
            origin_m[h] = forward.segment_origin_m[h * segments + segment];
          }
          frames_ready = true;
        }
        // The skeleton's frame is scored where the marker was measured and
        // helped place its segment: a fair score only if two more markers of
        // the segment hold it through the gap (a lone marker would score its
        // own segment perfect).
        int holders = 0;
        for (std::size_t m = 0; m < n; ++m) {
          if (m == i || marker_segments[m] != marker_segments[i]) continue;
          bool held = true;
          for (std::size_t g = before ? first - 1 : first; g < (after ? end + 1 : end) && held; ++g)
            held = visible[g * n + m] != 0;
          holders += held ? 1 : 0;
        }
        const FrameCandidate skeleton{q, origin_m, skeleton_m};
        if (!fill_from_donors(frames, n, times_s, fill.markers_m, visible, static_cast<int>(i),
                              first, end, donors, out_m, holders >= 2 ? &skeleton : nullptr,
                              &donor_share, std::span(nearby).subspan(i * n, n)))
          out_m = skeleton_m;
      } else {
        out_m = skeleton_m;
      }
      gap.method = donor_share >= 1.0 ? FillMethod::donors
                   : donor_share > 0.0 ? FillMethod::both
                                       : FillMethod::skeleton;
      for (std::size_t g = first; g < end; ++g) {
        fill.markers_m[g * n + i] = out_m[g - first];
        fill.filled[g * n + i] = 1;
      }
      fill.gaps.push_back(gap);
    }
  }
  return fill;
}

}  // namespace fabrik
