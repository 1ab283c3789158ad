// The tracker's robustness settings from a daemon config: `outliers` (outlier_filter.hpp,
// mirror_swap.hpp), `quality` (fit_quality.hpp), `cold_start` (cold_start.hpp), `confidence`
// and `smoothing` (one_euro.hpp). Lengths are millimetres in
// JSON (`*_mm` keys), metres inside.
#pragma once

#include "json_reader.hpp"
#include "tracking/tracker.hpp"

namespace fabrik {

// Reads whichever of those objects `root` has into `setup`; the others keep their
// defaults.
void read_tracking_options(const JsonReader& root, TrackerSetup& setup);

}  // namespace fabrik
