// `fabrik eval angles`: the model's named coordinates (joint angles, pelvis
// translations) on a recorded trial against a reference table of the same
// trial, such as OpenSim's inverse kinematics (.mot), over the frames both
// have, matched on time.
#pragma once

#include <string>
#include <vector>

#include "io/opensim_table.hpp"
#include "solver/model.hpp"
#include "subject.hpp"

namespace fabrik::eval {

struct AngleOptions {
  // A reference row matches the trial frame within this many seconds of it;
  // <= 0: a quarter of the trial's frame period.
  double time_tolerance_s = 0.0;
};

// One coordinate in both. Values in SI: radians for a rotation, metres for a
// translation (the tables print degrees and millimetres).
struct CoordinateComparison {
  std::string name;
  CoordinateKind kind = CoordinateKind::rotation;
  std::size_t samples = 0;
  double rms_si = 0.0;          // of fabrik - reference
  double offset_si = 0.0;       // mean of fabrik - reference
  double rms_centered_si = 0.0; // of fabrik - reference - offset
  double pearson_r = 0.0;       // NaN when either series moves less than 1e-6 (rad or m)
  double range_fabrik_si = 0.0, range_reference_si = 0.0;  // max - min (range of motion)
  std::vector<double> fabrik_si, reference_si;             // per shared frame
};

struct AngleReport {
  std::string reference_file;
  std::vector<double> time_s;  // the shared frames' times
  std::vector<std::size_t> frames;  // their trial frame indices
  std::vector<long long> frame_numbers;  // and numbers, as the trial counts them
  std::vector<CoordinateComparison> rows;  // the model's order
  std::vector<std::string> not_in_reference;  // model coordinates the reference lacks
  std::vector<std::string> not_in_model;      // reference columns the model lacks
  // The tracking run the angles come from (every trial frame).
  double residual_rms_mean_m = 0.0, residual_max_m = 0.0;
  long long residual_max_frame = 0;  // frame number, as the trial counts it
  std::string residual_max_marker;
};

// Throws std::invalid_argument when no reference row matches a trial frame
// or the model has no coordinates.
AngleReport eval_angles(const DaemonConfig& config, const io::MarkerTrial& trial,
                        const io::OpenSimTable& reference, const std::string& reference_file,
                        const AngleOptions& options = {});

}  // namespace fabrik::eval
