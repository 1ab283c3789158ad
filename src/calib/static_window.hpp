// How still a subject stood in a static trial's window, and the stillest window of N frames.
// A calibration averages each marker over the window: a subject who sways or shifts weight
// there gives a model of a posture nobody held.
#pragma once

#include <cstddef>
#include <vector>

#include "io/marker_trial.hpp"

namespace fabrik::calib {

// Warn above this: a few millimetres, about the noise of a good marker at rest plus some
// sway (the treadmill example moved 8.8 mm).
constexpr double kStillWindowWarn_m = 0.003;

struct WindowMotion {
  double motion_m = 0.0;  // largest distance of any sample from its marker's window mean
  int column = -1;        // the trial column of that marker, -1 when nothing was measured
  std::size_t missing = 0;  // samples of the columns missing in the window
};

// Over frames [first, first + count) of the given trial columns (negative ones skipped).
WindowMotion window_motion(const io::MarkerTrial& trial, const std::vector<int>& columns,
                           std::size_t first, std::size_t count);

// The first frame index of the window of `count` frames with the fewest missing samples and,
// among those, the least motion.
std::size_t stillest_window(const io::MarkerTrial& trial, const std::vector<int>& columns,
                            std::size_t count);

}  // namespace fabrik::calib
