// A verdict on one frame's fit that a client can act on: `good` when the marker residual is
// within thresholds the config sets (RMS and max, after OpenSim's guidance for inverse
// kinematics: RMS under 2 cm, max under 2-4 cm), `poor` when it is not, `none` when no marker
// was measured. The solver's own stop reason (converged, stalled, ...) says how the loop
// ended, not whether the pose fits: a stalled solve may be the best fit of noisy markers, or a
// metre off.
#pragma once

#include <cstdint>
#include <string_view>

namespace fabrik {

struct QualitySettings {
  double rms_m = 0.020;  // per-frame RMS over the markers that took part in the solve
  double max_m = 0.040;  // any one of them
};

enum class FitQuality : std::uint8_t { none, good, poor };

inline std::string_view to_string(FitQuality q) {
  switch (q) {
    case FitQuality::none:
      return "none";
    case FitQuality::good:
      return "good";
    case FitQuality::poor:
      return "poor";
  }
  return "none";
}

inline FitQuality judge_fit(const QualitySettings& s, int residual_count, double rms_m,
                            double max_m) {
  if (residual_count == 0) return FitQuality::none;
  return rms_m <= s.rms_m && max_m <= s.max_m ? FitQuality::good : FitQuality::poor;
}

}  // namespace fabrik
