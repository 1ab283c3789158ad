// Calibration: a template plus a static trial -> a subject's fabrikd-model/1
// model and a complete fabrikd-config/1 daemon config.
//
// The rest posture of the model IS the averaged static posture: every
// segment frame is parallel to the world at rest (see solver/model.hpp), so
// each point's local coordinate is its static world position minus the world
// position of its segment's base joint. Markers reproduce their static means
// exactly at rest; joint centres come from the template's rules.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "calib_template.hpp"
#include "config/lab_axes_json.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::calib {

// Something the calibration needs is missing or degenerate (a marker absent
// from the window, collinear frame markers, a window outside the trial).
class CalibrationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct CalibrateOptions {
  long long first_frame = -1;  // the file's frame number (as in TRC Frame#); -1: the first
  long long frames = -1;       // frames to average; -1: to the end of the trial
  long long auto_window = -1;  // > 0: average the stillest window of this many frames instead
  // The lab's axes as declared on the command line; they win over the
  // template's "lab_axes". Neither: detected from the static trial.
  std::optional<LabAxesSpec> lab_axes = std::nullopt;
};

struct SegmentLength {
  std::string segment, from, to;  // base -> a joint or end site of the segment
  double length_m = 0.0;
};

// How well the calibrated model reproduces a marker over the window: the
// written config tracked through the window as `fabrik solve` tracks it
// (the same Tracker and settings), RMS and max over the marker's samples
// that were solved with (outliers left out).
struct MarkerFit {
  std::string marker, segment;
  double rms_m = 0.0, max_m = 0.0;
  int samples = 0;
};

struct CalibrationResult {
  nlohmann::ordered_json model;   // fabrikd-model/1, millimetres
  nlohmann::ordered_json config;  // fabrikd-config/1 with the model inline
  long long first_frame = 0;      // the window, as file frame numbers
  long long frames = 0;
  // How much the subject moved in the window: the largest distance of a marker's sample from
  // its window mean, and that marker.
  double window_motion_m = 0.0;
  std::string window_motion_marker;
  std::vector<std::pair<std::string, Eigen::Vector3d>> points_world_m;  // every template point
  std::vector<SegmentLength> lengths;
  std::vector<MarkerFit> fits;
  double rest_max_m = 0.0;  // worst distance of a rest model marker to its static mean
  // The window's residual as `fabrik solve` reports it: the mean over frames
  // of each frame's RMS over its solved markers, the worst frame's RMS, and
  // the largest single residual with its marker and frame number.
  double fit_rms_mean_m = 0.0, fit_rms_worst_frame_m = 0.0, fit_max_m = 0.0;
  std::string fit_max_marker;
  long long fit_max_frame = 0;
  int fit_outlier_samples = 0;  // left out of their frame's solve by the outlier rule
  // The lab's axes written into the model ("lab_axes"), and how they were chosen.
  LabAxes lab_axes;
  std::string lab_axes_how;
  std::vector<std::string> notes;  // things the user should know (ignored labels, gaps)
  // Frames and coordinates derived because the template names no coordinates
  // (derive_anatomy.hpp), or why they could not be: one line each.
  std::vector<std::string> derived;
  // The rest posture was built (a keypoint template), not averaged from a static trial:
  // the window is the movement the lengths came from, and it is the one the fit tracks.
  bool built_rest = false;

  const Eigen::Vector3d& point_world_m(const std::string& name) const;
};

// `trial_name` is used in messages. Throws CalibrationError.
CalibrationResult calibrate(const CalibTemplate& tmpl, const io::MarkerTrial& trial,
                            const std::string& trial_name, const CalibrateOptions& options = {});

// The signed lab axis (+x, -z, ...) nearest v, other than the axis of `except` (zero: any).
Eigen::Vector3d nearest_lab_axis(const Eigen::Vector3d& v, const Eigen::Vector3d& except);

// A note when a declared up axis is more than 45 deg from the subject's measured superior
// direction (`superior_lab`, zero: none measured), saying which axis that is nearest;
// `measured` says what it was measured from. Nothing otherwise.
std::optional<std::string> declared_up_note(const Eigen::Vector3d& up_lab,
                                            const Eigen::Vector3d& superior_lab,
                                            const std::string& measured);

// Frames [first, first + count) (indices) of the trial from --first-frame (the file's frame
// number; -1: the first) and --frames (-1: to the end). Throws CalibrationError.
struct FrameWindow {
  std::size_t first = 0, count = 0;
  long long first_frame_number = 0;
};
FrameWindow frame_window(const io::MarkerTrial& trial, const std::string& trial_name,
                         long long first_frame, long long frames);

// A rest posture built rather than recorded (keypoint templates, keypoint_calibration.hpp):
// `rest` is one frame of every keypoint at rest, labelled as the movement trial is; every
// segment's anatomical frame is `axes_lab` (OpenSim's x anterior, y up, z right in the lab),
// and the fit tracks `fit_trial`'s window [fit_first, fit_first + fit_count).
struct BuiltRest {
  Eigen::Matrix3d axes_lab = Eigen::Matrix3d::Identity();
  const io::MarkerTrial* fit_trial = nullptr;
  std::size_t fit_first = 0, fit_count = 0;
  std::string source;  // how the rest posture was made, for the model's description
};
CalibrationResult calibrate_built_rest(const CalibTemplate& tmpl, const io::MarkerTrial& rest,
                                       const std::string& trial_name,
                                       const CalibrateOptions& options, const BuiltRest& built);

// The human-readable summary `fabrik calibrate` prints.
std::string calibration_report(const CalibrationResult& result);

}  // namespace fabrik::calib
