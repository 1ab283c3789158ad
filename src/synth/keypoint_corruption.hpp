// What a markerless pipeline does to keypoints that a marker system does not: per-axis
// jitter, short dropouts, and left/right label swaps (one mirrored pair, or every pair
// of a limb, for a few frames). Seeded and deterministic; every dropout and swap is
// returned, so an evaluation knows where they were. Solver types only: no I/O.
#pragma once

#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "solver/model.hpp"

namespace fabrik {

struct KeypointCorruption {
  double jitter_mm = 0.0;        // Gaussian, standard deviation per axis
  double dropouts_per_s = 0.0;   // runs of missing samples, each on a random keypoint
  int dropout_frames_max = 10;   // each run lasts 2 to this many frames
  double swaps_per_s = 0.0;      // left/right label swaps
  int swap_frames_max = 6;       // each lasts 2 to this many frames
  double limb_swap_share = 0.5;  // of the swaps: every pair of one limb (else one pair)
  unsigned seed = 1;
};

// One injected event over frames [first_frame, first_frame + frames).
struct InjectedRun {
  enum class Kind { dropout, swap_pair, swap_limb } kind = Kind::dropout;
  int first_frame = 0, frames = 0;
  std::vector<int> keypoints;  // dropout: the keypoint; swaps: right, left, right, left, ...
};
const char* injected_kind_name(InjectedRun::Kind kind);

// Mirrored keypoints: (right, left) indices of names that differ only in their side
// ("RKnee"/"LKnee", "right_knee"/"left_knee", "r_knee"/"l_knee", "knee_r"/"knee_l").
std::vector<std::pair<int, int>> mirrored_pairs(const std::vector<std::string>& names);

// A pair's limb: the top segment of the right keypoint's chain that the left keypoint's
// chain does not share (a thigh, a humerus); a pair on one segment (the shoulders) is a
// limb of its own. marker_points: per keypoint, its Model::points index.
std::vector<int> limbs_of_pairs(const Model& model, const std::vector<int>& marker_points,
                                const std::vector<std::pair<int, int>>& pairs);

// positions_m: frame-major [frame * keypoints + k], exact. limb_of_pair: per pair, a limb
// id (pairs of one limb share it). Swaps go first (labels trade positions), then jitter,
// then dropouts (NaN). Throws std::invalid_argument on impossible settings.
std::vector<InjectedRun> corrupt_keypoints(std::vector<Eigen::Vector3d>& positions_m,
                                           std::size_t keypoints, double rate_hz,
                                           const std::vector<std::pair<int, int>>& pairs,
                                           const std::vector<int>& limb_of_pair,
                                           const KeypointCorruption& c);

}  // namespace fabrik
