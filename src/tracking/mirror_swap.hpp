// Mirrored left/right swaps: a markerless pipeline's keypoints sometimes jump to the other leg
// (RHip, RKnee, RAnkle, RHeel ... exchanged with the left's for a few frames). The pairwise
// outlier rule (outlier_filter.hpp) cannot undo that: it leaves out at most a few markers a
// frame, and a whole swapped leg keeps its distances within itself, so it does not look moved.
//
// The rule, before the solve of a warm frame: for each left/right pair with both measured,
// compare the labelled assignment's distance to the predicted posture's points (the previous
// frame's, carried on by the warm start) with the mirrored one's; take the mirror when it is
// far closer (OutlierSettings::mirror_ratio) and the labelled one is clearly off
// (mirror_floor_m), for at most mirror_max_s at a stretch. Each pair is judged alone, so a whole limb, a part of one, or both arms and
// legs at once are undone alike. Nothing is allocated per frame.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "tracking/tracking_settings.hpp"

namespace fabrik {

// Pairs (right, left) of indices into `names` whose names mirror each other: one with a right
// prefix or suffix (R, r, Right, right, RIGHT; a suffix as _r, _R, _right, Right) whose left
// counterpart (L, l, Left, ...) is also in `names` (RHip/LHip, RKNE/LKNE, R.Thigh/L.Thigh,
// r_hip/l_hip, right_knee/left_knee, knee_r/knee_l). Each name in one pair at most.
std::vector<std::array<int, 2>> mirror_pairs_from_names(const std::vector<std::string>& names);

// The first marker that is in two of `pairs`, or -1. Such a marker would be swapped twice in
// one frame (the second swap undoing or crossing the first), as pairs found from names never
// are: the config loader and the tracker refuse it.
int marker_in_two_pairs(std::span<const std::array<int, 2>> pairs);

class MirrorSwap {
 public:
  MirrorSwap(OutlierSettings settings, std::vector<std::array<int, 2>> pairs);
  const std::vector<std::array<int, 2>>& pairs() const { return pairs_; }

  // Exchanges the measurements of every pair (both `seen`) whose mirror fits `predicted_m`
  // (per marker: its point in the predicted posture) far better, for at most mirror_max_s at a
  // stretch; sets relabelled_from for both and returns how many markers were relabelled.
  int apply(double time_s, std::span<Eigen::Vector3d> measured_m,
            std::span<const std::uint8_t> seen, std::span<const Eigen::Vector3d> predicted_m,
            std::span<int> relabelled_from);
  // Forgets every stretch (a cold frame).
  void reset();

 private:
  OutlierSettings settings_;
  std::vector<std::array<int, 2>> pairs_;
  std::vector<double> since_s_;  // per pair: when its mirror began to fit better, NaN if not
};

}  // namespace fabrik
