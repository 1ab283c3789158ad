// `fabrik eval gaps`: withhold one marker for a window and compare the
// model's gap-filled position with the real one.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "subject.hpp"

namespace fabrik::eval {

// live: the daemon's causal prediction (frames after the gap unseen);
// offline: `fabrik solve`'s two-sided fill (two_sided_fill.hpp).
enum class GapMode { live, offline };

struct GapOptions {
  std::vector<double> windows_s{0.1, 0.5, 1.0, 2.0};
  std::vector<GapMode> modes{GapMode::live, GapMode::offline};
  double stride_s = 0.5;             // window starts: 0, stride, 2 stride, ... (within the trial)
  std::vector<std::string> markers;  // withheld in turn; empty: every tracked marker in the trial
};

struct GapStats {
  std::string marker;
  GapMode mode = GapMode::live;
  double window_s = 0.0;
  int windows = 0, samples = 0;
  double rms_m = 0.0, max_m = 0.0;              // predicted vs withheld real position
  double joint_rms_m = 0.0, joint_max_m = 0.0;  // reference points vs the all-markers solution (live)
  // Live, when the marker returns: the largest step of a joint centre or end
  // site beyond the larger of its steps in the frames before and after (m).
  double return_jump_m = 0.0;
};

struct GapSummary {
  GapMode mode = GapMode::live;
  double window_s = 0.0;
  int markers = 0, windows = 0;
  double median_rms_m = 0.0, median_max_m = 0.0, worst_rms_m = 0.0;
  std::string worst_marker;
  double joint_rms_m = 0.0, joint_max_m = 0.0;  // over all gaps (live)
  double return_jump_m = 0.0;                   // the largest over all gaps (live)
};

// One withheld window: the real (measured) and predicted (model) positions.
struct GapTrace {
  std::string marker;
  GapMode mode = GapMode::live;
  double window_s = 0.0;
  std::size_t first_frame = 0;  // frame index (GapReport::clock names it)
  std::vector<Eigen::Vector3d> real_m, predicted_m;
};

struct GapReport {
  double rate_hz = 0.0;
  io::FrameClock clock;  // the trial's frame numbers and times, to name frames by
  std::vector<GapStats> rows;  // per marker and window length
  std::vector<GapSummary> summary;
  std::vector<GapTrace> traces;
};

const char* to_string(GapMode mode);

GapReport eval_gaps(const DaemonConfig& config, const io::MarkerTrial& trial,
                    const GapOptions& options = {});

}  // namespace fabrik::eval
