// Offline fill of one marker's gap from other measured markers that move with
// it (a "rigid body" or local-coordinate-system fill, as in Vicon Nexus and
// Howarth & Callaghan), with the donors chosen from the trial's own data:
// candidates are the markers whose distance to the filled one varied least
// while both were measured; every triple of them spans a frame in which the
// marker's coordinates are interpolated linearly across the gap, and the
// triples are scored by doing exactly that on gaps of the same length
// simulated where everything was measured (cross-validation). The best
// triples' fills are averaged, weighted by their scores. Needs no model: it
// reproduces what the markers did, soft tissue included, where the skeleton
// can only put the marker at its calibrated place on its segment.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <span>

namespace fabrik {

struct DonorFillSettings {
  int candidates = 8;        // donors ranked by the spread of their distance to the marker
  int triples = 3;           // best-scored triples averaged
  double min_sine = 0.2;     // a triple's triangle must not be flatter (sine of its angle at the first)
  double score_floor_m = 3e-4;  // weights are 1 / max(score, floor)^2: marker noise
  // Donors whose best simulated-gap error is beyond this are not used: the
  // skeleton's fill, off by about its calibration misfit, is then the better bet.
  double max_score_m = 0.02;
  // Only frames this close to the gap are scored: at least this long, and at
  // least this many gap lengths, either side (motion far from the gap says less).
  double context_s = 5.0;
  double context_gaps = 5.0;
};

// One more candidate besides the donor triples: a rigid frame per trial frame
// (the marker's segment as the skeleton tracked it), scored the same way, with
// its own fill of the gap.
struct FrameCandidate {
  std::span<const Eigen::Quaterniond> q_world;  // [frame]
  std::span<const Eigen::Vector3d> origin_m;    // [frame]
  std::span<const Eigen::Vector3d> fill_m;      // [end - first]
};

// Marker `marker`'s gap, frames [first, end), of a trial of `frames` frames
// and `n` markers (markers_m and visible: [frame * n + i], metres); its sides are the
// frames next to it where the marker is measured (a gap may end one frame short of them). Writes
// end - first positions to `out` and returns true, or returns false (out
// untouched) when no triple of donors is measured throughout the gap and on
// its measured sides, none can be scored, or the best scores beyond max_score_m.
// With a skeleton candidate, it competes with the triples (and max_score_m
// does not apply); donor_share gets the donors' share of the weights.
// allowed (n entries, empty: all): the markers that may be donors.
bool fill_from_donors(std::size_t frames, std::size_t n, std::span<const double> times_s,
                      std::span<const Eigen::Vector3d> markers_m,
                      std::span<const std::uint8_t> visible, int marker, std::size_t first,
                      std::size_t end, const DonorFillSettings& settings,
                      std::span<Eigen::Vector3d> out, const FrameCandidate* skeleton = nullptr,
                      double* donor_share = nullptr, std::span<const std::uint8_t> allowed = {});

}  // namespace fabrik
