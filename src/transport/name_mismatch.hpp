// A stream that shares no marker name with the config: every frame would be solved with no
// target and report a residual of 0 mm. The daemon cannot refuse it (the source may be
// switched to the right subject any time), so it says so loudly, once, with the closest
// names, and in stats. A few such frames in a row are needed, so that a frame holding only
// another subject's or a prop's markers does not trigger it.
#pragma once

namespace fabrik::wire {

class NameMismatchWatch {
 public:
  // Consecutive frames with marker names, none of them the config's, before the stream is
  // taken as not matching.
  static constexpr int kFramesInARow = 10;

  // One decoded frame: `known` names of the config, `unknown` others. Returns true once, on
  // the frame where the stream is first taken as not matching (time to warn).
  bool observe(int known, int unknown) {
    if (known > 0) {
      in_a_row_ = 0;
      mismatched_ = false;
      return false;
    }
    if (unknown == 0) return false;  // an empty frame says nothing about the names
    if (++in_a_row_ < kFramesInARow) return false;
    mismatched_ = true;
    if (warned_) return false;
    warned_ = true;
    return true;
  }
  // Whether the latest frames with names share none with the config.
  bool mismatched() const { return mismatched_; }

 private:
  int in_a_row_ = 0;
  bool mismatched_ = false, warned_ = false;
};

}  // namespace fabrik::wire
