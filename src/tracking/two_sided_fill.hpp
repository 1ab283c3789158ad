// Offline gap filling, where both sides of a gap are known: the Tracker runs
// forward in time and, separately, backward (time reversed), each predicting
// the gap from its own side (GapPredictor); a gap's fill is the two
// predictions blended linearly across it, so it starts at the forward one
// (continuous with the last sample before the gap) and ends at the backward
// one (continuous with the first sample after it). A gap at the start of the
// trial takes the backward prediction alone, one at the end the forward one; a
// marker never measured is not filled.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "tracker.hpp"

namespace fabrik {

struct FilledGap {
  int marker = 0;              // index into the setup's markers
  std::size_t first = 0, end = 0;  // frames [first, end)
};

struct TwoSidedFill {
  std::size_t frames = 0, n = 0;
  std::vector<Eigen::Vector3d> markers_m;  // [frame * n + i]: measured, filled, or NaN (never measured)
  std::vector<std::uint8_t> filled;        // [frame * n + i]
  std::vector<FilledGap> gaps;             // by marker, then by frame
};

// times_s: per frame, increasing; measured_m and visible: [frame * n + i],
// n = setup.markers.size().
TwoSidedFill fill_two_sided(const TrackerSetup& setup, std::span<const double> times_s,
                            std::span<const Eigen::Vector3d> measured_m,
                            std::span<const std::uint8_t> visible);

}  // namespace fabrik
