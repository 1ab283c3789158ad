// The least (and for fractions the most) value of a tracking setting that a frame can run
// with: one owner for the Tracker's setup check (tracker_core.cpp) and the config reader's
// ranges (config/tracking_options_json.cpp), which adds upper bounds of its own for sanity.
#pragma once

namespace fabrik::settings_bounds {

inline constexpr double kLeastCutoffHz = 1e-3;       // One Euro cutoffs: 0 freezes a marker
inline constexpr double kLeastOutlierFloorM = 1e-3;  // outliers.floor_m
inline constexpr double kLeastMedianFactor = 1.0;    // outliers.median_factor
inline constexpr int kLeastOutlierMarkers = 3;       // outliers.min_markers: a rigid fit's least
inline constexpr double kMostFraction = 1.0;         // mirror_ratio, confidence.threshold
inline constexpr int kLeastColdIterations = 1;       // cold_start.max_iterations

}  // namespace fabrik::settings_bounds
