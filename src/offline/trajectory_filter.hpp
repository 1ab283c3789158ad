// A zero-lag low-pass filter of recorded marker trajectories, for `fabrik solve --filter-hz`:
// a 2nd-order Butterworth run forward and then backward over each marker's samples (filtfilt:
// no phase shift, the magnitude response squared, -6 dB at the cutoff). Pose2Sim filters its
// triangulated keypoints the same way (a Butterworth of order 4 in all, cutoff 6 Hz by default).
//
// Each contiguous run of measured (finite) samples is filtered on its own and gaps stay gaps:
// nothing is carried across a gap, and no sample is invented. Each run's ends are extended by
// odd reflection (as scipy's filtfilt) so a run starts and ends without a transient; a run of
// fewer samples than that extension needs is left as it is.
#pragma once

#include <cstddef>
#include <span>

#include "io/marker_trial.hpp"

namespace fabrik {

// The digital 2nd-order Butterworth low-pass of this cutoff at this sample rate (bilinear
// transform, prewarped): y[n] = b0 x[n] + b1 x[n-1] + b2 x[n-2] - a1 y[n-1] - a2 y[n-2].
struct Butterworth2 {
  double b0 = 1.0, b1 = 0.0, b2 = 0.0, a1 = 0.0, a2 = 0.0;
  static Butterworth2 low_pass(double cutoff_hz, double rate_hz);
};

// Samples each end of a run is extended by: scipy's filtfilt default, 3 * max(len(a), len(b)).
constexpr std::size_t kFiltfiltPad = 9;

// Filters `x` (finite samples, one run) forward and backward in place; fewer than
// kFiltfiltPad + 1 samples are left as they are. Allocates its scratch.
void filtfilt(const Butterworth2& f, std::span<double> x);

// Filters every marker's runs of measured samples in place (see the file's description).
// Throws std::invalid_argument unless 0 < cutoff_hz < trial.rate_hz / 2.
void filtfilt_trial(io::MarkerTrial& trial, double cutoff_hz);

}  // namespace fabrik
