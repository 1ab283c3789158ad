// A marker's confidence as a frame gives it (a keypoint detector's score), read one way by
// every reader: the daemon's wire codecs and the Python Tracker.
#pragma once

#include <algorithm>
#include <cmath>
#include <optional>

namespace fabrik {

// Clamped to [0, 1] (detectors' scores may stray a little past 1); nothing for a value that
// is not finite, which says nothing about the marker: the reader occludes it.
inline std::optional<float> clamped_confidence(double confidence) {
  if (!std::isfinite(confidence)) return std::nullopt;
  return static_cast<float>(std::clamp(confidence, 0.0, 1.0));
}

}  // namespace fabrik
