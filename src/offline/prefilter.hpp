// Zero-lag filtering that a swap or an outlier cannot smear. Filtering a recording as it is
// blends a swapped or wild sample into its neighbours before the tracker's rules (outliers,
// swapped labels: outlier_filter.hpp, mirror_swap.hpp) can see it standing out. So a first
// pass tracks the trial as recorded; a label it took as swapped (pairwise or mirrored) gets the
// sample it was solved with (the other label's), and a sample it left out of its solve as an
// outlier becomes a gap (so does a relabelled one whose source marker the trial lacks); then
// each run of the remaining samples is low-passed with zero lag (trajectory_filter.hpp). The
// caller then tracks the result.
#pragma once

#include <cstddef>

#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"

namespace fabrik {

// Returns the samples relabelled or turned into gaps. Throws std::invalid_argument as filtfilt_trial does.
std::size_t drop_left_out_then_filter(const DaemonConfig& config, io::MarkerTrial& trial,
                                      double cutoff_hz);

}  // namespace fabrik
