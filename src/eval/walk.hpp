// `fabrik eval walk`: marker residuals of a calibrated subject on a recorded
// trial, and the rigid-cluster bound (each segment's markers fitted alone).
#pragma once

#include <string>
#include <vector>

#include "subject.hpp"

namespace fabrik::eval {

struct MarkerStats {
  std::string marker, segment;
  double rms_m = 0.0, max_m = 0.0;
  int samples = 0;
};

struct WalkReport {
  double rate_hz = 0.0;
  io::FrameClock clock;  // the trial's frame numbers and times, to name frames by
  std::vector<double> rms_m, max_m;  // per frame, over measured markers
  std::vector<std::string> worst;    // per frame
  // Per frame, the worst marker residual of an unconstrained rigid fit of
  // each segment's calibrated markers alone (no joints): what the data's own
  // non-rigidity (skin, shoe, marker glitches) leaves for any rigid segment.
  std::vector<double> cluster_max_m;
  std::vector<std::string> cluster_worst;
  double rms_mean_m = 0.0, rms_worst_m = 0.0;
  double max_m_over_frames = 0.0;
  long long max_frame = 0;  // frame numbers as the trial counts them
  std::string max_marker;
  double cluster_max_over_frames_m = 0.0;
  long long cluster_max_frame = 0;
  std::string cluster_max_marker;
  double iterations_mean = 0.0;
  std::vector<MarkerStats> markers;  // the tracker's marker order
};

WalkReport eval_walk(const DaemonConfig& config, const io::MarkerTrial& trial);

}  // namespace fabrik::eval
