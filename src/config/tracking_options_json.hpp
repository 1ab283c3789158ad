// The tracker's robustness settings from a daemon config: `outliers` (outlier_filter.hpp),
// `quality` (fit_quality.hpp) and `cold_start` (cold_start.hpp). Lengths are millimetres in
// JSON (`*_mm` keys), metres inside.
#pragma once

#include "json_reader.hpp"
#include "tracking/tracker.hpp"

namespace fabrik {

// Reads whichever of the three objects `root` has into `setup`; the others keep their
// defaults.
void read_tracking_options(const JsonReader& root, TrackerSetup& setup);

}  // namespace fabrik
