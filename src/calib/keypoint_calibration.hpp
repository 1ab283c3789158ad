// Calibration from markerless keypoints (templates with "kind": "keypoints",
// docs/keypoints.md): no static trial. Each segment length is the median, over a
// window of any movement, of the distance between two keypoints (corrected for the
// keypoints' jitter, which lengthens a distance on average), with its spread; the
// rest posture is the template's standing posture at those lengths, and frames,
// joints, ranges and coordinates are the template's. The result is a calibrated
// config as `fabrik calibrate` writes from a static trial.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "calibrate.hpp"

namespace fabrik::calib {

struct KeypointCalibrateOptions {
  long long first_frame = -1;  // the file's frame number; -1: the first
  long long frames = -1;       // frames to measure over; -1: to the end of the trial
  // Declared lab axes (win over the template's); neither: up detected from the movement.
  std::optional<LabAxesSpec> lab_axes = std::nullopt;
  // A length is flagged when its IQR exceeds this share of its median or wide_spread_min_m,
  // whichever is larger (a keypoint that swaps, or a joint centre the detector misplaces).
  double wide_spread_share = 0.10;
  double wide_spread_min_m = 0.015;
};

// One measured length: point `point` from `from` (its segment's base unless the template
// names another), over the window's frames where both are seen.
struct KeypointLength {
  std::string segment, point, from;
  double median_raw_m = 0.0;  // median of the per-frame distances
  double median_m = 0.0;      // corrected for jitter: the length used
  double iqr_m = 0.0;         // interquartile range of the per-frame distances
  double mad_m = 0.0;         // median absolute deviation from median_raw_m
  int samples = 0;
  bool wide = false;
};

struct KeypointCalibration {
  CalibrationResult result;             // model and config, as calibrate() returns them
  std::vector<KeypointLength> lengths;  // every measured length, in template order
  // Per-keypoint jitter estimated from second differences (per axis, m), by keypoint name.
  std::vector<std::pair<std::string, double>> jitter_m;
  std::vector<std::string> absent_optional;  // optional keypoints the trial lacks
};

// Throws CalibrationError (or ConfigError for a template mistake found late).
KeypointCalibration calibrate_keypoints(const CalibTemplate& tmpl, const io::MarkerTrial& trial,
                                        const std::string& trial_name,
                                        const KeypointCalibrateOptions& options = {});

// The template at its nominal lengths (the rest vectors' lengths), standing 0.95 m up
// (root) in the declared lab axes, else the template's, else Y up and X forward: the truth
// model of `fabrik synth --keypoints` (`fabrik calibrate --nominal`).
KeypointCalibration nominal_keypoint_model(const CalibTemplate& tmpl,
                                           const std::optional<LabAxesSpec>& lab_axes = {});

// The lengths table `fabrik calibrate` prints before calibration_report().
std::string keypoint_length_report(const KeypointCalibration& k);
// The same as JSON (--lengths-json).
nlohmann::ordered_json keypoint_lengths_json(const KeypointCalibration& k);

}  // namespace fabrik::calib
