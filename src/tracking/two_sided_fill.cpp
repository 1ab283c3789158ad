#include "two_sided_fill.hpp"

#include <cmath>

namespace fabrik {

namespace {

// The model's markers per frame, tracking the frames in the given order
// (backward: times negated, so the tracker's clock still runs forward).
std::vector<Eigen::Vector3d> track_pass(const TrackerSetup& setup, std::span<const double> times_s,
                                        std::span<const Eigen::Vector3d> measured_m,
                                        std::span<const std::uint8_t> visible, bool backward) {
  Tracker tracker(setup);
  const std::size_t n = setup.markers.size(), frames = times_s.size();
  std::vector<Eigen::Vector3d> out(frames * n);
  for (std::size_t k = 0; k < frames; ++k) {
    const std::size_t f = backward ? frames - 1 - k : k;
    const TrackResult& r = tracker.track(backward ? -times_s[f] : times_s[f],
                                         measured_m.subspan(f * n, n), visible.subspan(f * n, n));
    std::copy(r.markers_world_m.begin(), r.markers_world_m.end(), out.begin() + f * n);
  }
  return out;
}

}  // namespace

TwoSidedFill fill_two_sided(const TrackerSetup& setup, std::span<const double> times_s,
                            std::span<const Eigen::Vector3d> measured_m,
                            std::span<const std::uint8_t> visible) {
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
  const std::vector<Eigen::Vector3d> forward = track_pass(setup, times_s, measured_m, visible, false);
  const std::vector<Eigen::Vector3d> backward = track_pass(setup, times_s, measured_m, visible, true);
  for (std::size_t i = 0; i < n; ++i) {
    std::size_t f = 0;
    while (f < frames) {
      if (visible[f * n + i]) {
        ++f;
        continue;
      }
      const std::size_t first = f;
      while (f < frames && !visible[f * n + i]) ++f;
      const bool before = first > 0, after = f < frames;
      if (!before && !after) continue;  // never measured: nothing to fill from
      for (std::size_t g = first; g < f; ++g) {
        // Weight of the backward prediction: 0 at the last sample before the
        // gap, 1 at the first one after it.
        const double w = !before ? 1.0
                         : !after ? 0.0
                                  : static_cast<double>(g - first + 1) /
                                        static_cast<double>(f - first + 1);
        const std::size_t k = g * n + i;
        fill.markers_m[k] = (1.0 - w) * forward[k] + w * backward[k];
        fill.filled[k] = 1;
      }
      fill.gaps.push_back({static_cast<int>(i), first, f});
    }
  }
  return fill;
}

}  // namespace fabrik
