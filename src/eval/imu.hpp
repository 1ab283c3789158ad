// `fabrik eval imu`: orientation sensors (IMUs) against the truth on
// synthetic motion (markers only, IMUs only, pelvis markers plus IMUs on every
// other segment), and the OpenSense walk tracked from its 8 IMUs alone, with
// gait checks on its knee and hip angles.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "config/daemon_config.hpp"
#include "io/orientation_table.hpp"
#include "offline/solve_trial.hpp"

namespace fabrik::eval {

struct ImuSyntheticOptions {
  double seconds = 10.0;
  double rate_hz = 100.0;
  double marker_noise_mm = 1.0;      // per axis, Gaussian
  double sensor_noise_deg = 1.0;     // per sensor axis, Gaussian
  double drift_deg_per_s = 0.05;     // each sensor's heading drifts at a rate within +-this
  double calibration_s = 1.0;        // standing still in the rest posture before the motion
  unsigned seed = 1;
};

struct ImuSyntheticRow {
  std::string setup;  // "markers only", "IMUs only", "pelvis markers + IMUs"
  std::size_t markers = 0, sensors = 0, frames = 0;
  // Every joint's rotation (child relative to parent) vs the truth: RMS and max angle.
  double joint_angle_rms_rad = 0.0, joint_angle_max_rad = 0.0;
  // Joint centres vs the truth (IMUs only: the root is held, so this includes its travel).
  double joint_rms_m = 0.0, joint_max_m = 0.0;
};

// `config`'s model (every segment gets a simulated sensor) and markers.
std::vector<ImuSyntheticRow> eval_imu_synthetic(const DaemonConfig& config,
                                                const ImuSyntheticOptions& options = {});

// Gait checks on a tracked walk's coordinates (OpenSim Gait2354 names and
// signs: knee_angle_* negative in flexion).
struct GaitStride {
  char side = 'r';
  double time_s = 0.0;          // of the knee flexion peak
  double knee_flexion_deg = 0.0;
};
struct GaitReport {
  std::size_t frames = 0, frames_tracked = 0;  // tracked: a solve with targets, finite pose
  std::vector<GaitStride> strides;             // knee flexion peaks (swing), in time order
  double knee_flexion_min_deg = 0.0;           // both sides
  double hip_flexion_min_deg = 0.0, hip_flexion_max_deg = 0.0;
  bool alternating = false;                    // L and R peaks alternate
  double max_jump_deg = 0.0;                   // frame to frame, any rotation, as written
  std::string max_jump_coordinate;
  long long max_jump_frame = 0;                // the later frame, numbered as the source does
  double sensor_error_rms_deg = 0.0;           // mean over frames
};
GaitReport gait_report(const TrialSolution& s);

// Calibrates `template_path` on the static marker trial and the placement
// orientations (the subject in the template's calibration pose), then tracks
// the walk's orientations alone.
struct OpenSenseRun {
  DaemonConfig config;
  TrialSolution solution;
  GaitReport report;
};
OpenSenseRun eval_imu_opensense(const std::string& template_path, const std::string& static_path,
                                const std::string& placement_path, const std::string& walk_path);

std::string imu_synthetic_table(const std::vector<ImuSyntheticRow>& rows,
                                const ImuSyntheticOptions& options);
std::string gait_table(const GaitReport& r);

}  // namespace fabrik::eval
