// Which whole turn each rotational coordinate is written on, frame after frame.
#pragma once

#include <span>
#include <vector>

#include "solver/model.hpp"

namespace fabrik {

// Rotational coordinates continuous over frames, as OpenSim's (which never wrap at +-180 deg),
// without a flip walking them off by whole turns. Each rotation is written as the whole-turn
// equivalent nearest its branch: the last value reached by a step of at most 90 deg. A frame
// that jumps further (a left/right swap turns the pelvis 180 deg) is written near the branch
// but does not move it, so flips back and forth cannot add up to turns (they did: -1100 deg
// against a truth of -22 after a few keypoint swaps). A jump that lasts kJumpKept_s is motion
// (after a gap, say) and becomes the branch.
class CoordinateBranch {
 public:
  static constexpr double kLargestStep_rad = 1.5707963267948966;  // 90 deg: no body turns faster
                                                                  // in one frame at >= 10 Hz
  static constexpr double kJumpKept_s = 0.5;

  explicit CoordinateBranch(const Model& model);

  // Moves the rotations of `coordinates` (principal values, Model::coordinates order) onto
  // their branch at `time_s`. With `continues` false (a first frame, a reset, a clock that went
  // back) they are left as they are and start the branch. Allocates nothing.
  void follow(double time_s, std::span<double> coordinates, bool continues);

 private:
  std::vector<double> branch_;        // per coordinate: the branch's value (rotations only)
  std::vector<double> jump_since_s_;  // per coordinate: when the running jump began, or NaN
  std::vector<double> turn_;          // per coordinate: a whole turn of its value; 0: translation
};

}  // namespace fabrik
