// A verdict on one frame's fit that a client can act on: `good` when the marker residual is
// within thresholds the config sets (RMS and max, after OpenSim's guidance for inverse
// kinematics: RMS under 2 cm, max under 2-4 cm), `poor` when it is not, `none` when no marker
// was measured. The solver's own stop reason (converged, stalled, ...) says how the loop
// ended, not whether the pose fits: a stalled solve may be the best fit of noisy markers, or a
// metre off.
#pragma once

#include <cstdint>
#include <string_view>

#include "tracking/tracking_settings.hpp"

namespace fabrik {

inline FitQuality judge_fit(const QualitySettings& s, int residual_count, double rms_m,
                            double max_m) {
  if (residual_count == 0) return FitQuality::none;
  return rms_m <= s.rms_m && max_m <= s.max_m ? FitQuality::good : FitQuality::poor;
}

}  // namespace fabrik
