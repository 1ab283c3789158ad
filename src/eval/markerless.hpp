// `fabrik eval markerless`: a markerless trial of our own making (docs/keypoints.md). A
// keypoint template at its nominal lengths is the truth model; its synthetic motion is
// rendered as keypoints with jitter, dropouts and left/right swaps (`fabrik synth
// --keypoints`); the template is calibrated from that trial alone (no static trial) and
// the trial tracked frame by frame through the Tracker; joint centres and coordinates
// are compared with the truth.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "synth/keypoint_corruption.hpp"

namespace fabrik::eval {

struct MarkerlessOptions {
  std::string template_path = "config/templates/halpe26.json";
  double seconds = 20.0;
  double rate_hz = 60.0;  // a video pipeline's rate
  unsigned seed = 1;
  // The corruption of the cases that switch it on (the rest of it: KeypointCorruption).
  KeypointCorruption corruption{15.0, 1.0, 10, 1.0, 6, 0.5, 1};
  // clean, jitter, dropouts, swaps, all: each switches on its part of `corruption`.
  std::vector<std::string> cases{"clean", "jitter", "dropouts", "swaps", "all"};
  // Merged into the calibrated config (RFC 7396 merge patch) before it is loaded: tracking
  // options (filters, outlier rule, occlusion) as a config would set them.
  nlohmann::json config_overrides = nlohmann::json::object();
  // Instead of generating: a trial `fabrik synth --keypoints` wrote (its truth files beside
  // it); evaluated as one case, "file".
  std::string trial_path;
  // live: frame by frame as recorded; offline: the keypoints low-passed at filter_hz by a
  // zero-lag Butterworth (offline/trajectory_filter.hpp) before the same tracking.
  std::string path = "live";
  double filter_hz = 6.0;  // offline only; Pose2Sim's default cutoff
};

struct CoordinateError {
  std::string name;
  double rms_deg = 0.0, max_deg = 0.0;
};

struct MarkerlessRow {
  std::string name;
  KeypointCorruption corruption;
  std::size_t frames = 0;
  double rate_hz = 0.0;  // the trial's
  int dropouts = 0, swaps = 0, swapped_frames = 0;
  // Calibration: each measured length against the truth's nominal one.
  double length_error_max_m = 0.0, length_error_rms_m = 0.0;
  std::string length_error_worst;
  int wide_lengths = 0;
  // Joint centres against the truth, over every joint and frame.
  double joint_rms_m = 0.0, joint_p95_m = 0.0, joint_max_m = 0.0;
  std::string joint_max_name;
  double joint_rms_swapped_m = 0.0;  // over frames inside a swap and the 5 after it
  double joint_rms_clean_m = 0.0;    // over the other frames
  // Rotational coordinates against the truth (deg).
  std::vector<CoordinateError> angles;
  double angle_rms_mean_deg = 0.0;
  // The shift (frames, 0-10) of the tracked coordinates that best matches the truth.
  int lag_frames = 0;
};

std::vector<MarkerlessRow> eval_markerless(const MarkerlessOptions& options);

std::string markerless_table(const std::vector<MarkerlessRow>& rows,
                             const MarkerlessOptions& options);
nlohmann::json markerless_json(const std::vector<MarkerlessRow>& rows);

}  // namespace fabrik::eval
