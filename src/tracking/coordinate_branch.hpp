// Which whole turn each rotational coordinate is written on, frame after frame.
#pragma once

#include <numbers>
#include <span>
#include <vector>

#include "solver/model.hpp"

namespace fabrik {

// Rotational coordinates continuous over frames, as OpenSim's (which never wrap at +-180 deg),
// without left/right swaps walking them off by whole turns: a swap turns the pelvis about
// 180 deg for a few frames, and "nearest the frame before" picks either side of a half turn,
// so flips back and forth could add up to turns.
//
// Each rotation keeps a branch: its last value reached by a step a body can make, at most
// kFastestTurn_rad_per_s over the time since (90 deg at least, kTellable_rad at most). A value
// within that of the branch is written on it and moves it. A value farther (a jump) is written
// nearest the frame before, the branch kept, so the frame after a swap comes back to the
// branch, whatever side the swap's frames were written on; a jump that lasts kJumpKept_s is
// motion (a turn during a gap) and becomes the branch. Where one frame interval allows a body
// kTellable_rad (below about 9 Hz) a swap cannot be told from a turn: nearest the frame before.
class CoordinateBranch {
 public:
  // Faster than a pirouette (2-3 turns a second): a step beyond it is no turn of a body.
  static constexpr double kFastestTurn_rad_per_s = 1200.0 * std::numbers::pi / 180.0;
  static constexpr double kSmallestLimit_rad = std::numbers::pi / 2;
  static constexpr double kTellable_rad = 0.75 * std::numbers::pi;  // 135 deg
  static constexpr double kJumpKept_s = 0.5;

  explicit CoordinateBranch(const Model& model);

  // Moves the rotations of `coordinates` (principal values, Model::coordinates order, from
  // coordinate_values) onto their branch at `time_s`. With `continues` false (a first frame, a
  // reset, a clock that went back) they are left as they are and start afresh. Allocates
  // nothing.
  void follow(double time_s, std::span<double> coordinates, bool continues);

 private:
  const Model& model_;
  std::vector<double> branch_;        // per coordinate: the branch's value, NaN: none yet
  std::vector<double> branch_s_;      // per coordinate: when the branch last moved
  std::vector<double> jump_since_s_;  // per coordinate: when the running jump began, or NaN
  std::vector<double> written_;       // per coordinate: the value written the frame before
  std::vector<double> near_written_;  // scratch: this frame's values nearest written_
  double previous_s_ = 0.0;           // the frame before's time
};

}  // namespace fabrik
