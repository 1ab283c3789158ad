// Offline gap filling, where both sides of a gap are known. The skeleton's
// fill: the Tracker runs forward in time and, separately, backward (time
// reversed), each predicting the gap from its own side (GapPredictor); the two
// predictions are blended linearly across the gap, so the fill starts at the
// forward one (continuous with the last sample before the gap) and ends at the
// backward one (continuous with the first sample after it); a gap at the start
// of the trial takes the backward prediction alone, one at the end the forward
// one. That fill competes with fills from donor markers (donor_fill.hpp), each
// scored on gaps simulated where the marker was measured; the best are
// averaged by score. A marker never measured is not filled, nor frames before the first or
// after the last frame with any measured marker (nothing to fill them from).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "donor_fill.hpp"
#include "live_marker_fill.hpp"
#include "tracker.hpp"

namespace fabrik {

// How a gap was filled: from donor markers, from the skeleton, or a weighted mix.
enum class FillMethod { donors, skeleton, both };
const char* to_string(FillMethod method);

struct FilledGap {
  int marker = 0;              // index into the setup's markers
  std::size_t first = 0, end = 0;  // frames [first, end)
  FillMethod method = FillMethod::skeleton;
};

struct TwoSidedFill {
  std::size_t frames = 0, n = 0;
  std::vector<Eigen::Vector3d> markers_m;  // [frame * n + i]: measured, filled, or NaN
  std::vector<std::uint8_t> filled;        // [frame * n + i]
  std::vector<FilledGap> gaps;             // by marker, then by frame
};

// times_s: per frame, increasing; measured_m and visible: [frame * n + i],
// n = setup.markers.size().
TwoSidedFill fill_two_sided(const TrackerSetup& setup, std::span<const double> times_s,
                            std::span<const Eigen::Vector3d> measured_m,
                            std::span<const std::uint8_t> visible,
                            const DonorFillSettings& donors = {}, bool use_donors = true);

}  // namespace fabrik
