// Accuracy evaluations behind `fabrik eval`: marker residuals on a recorded
// trial, gap filling against withheld real markers, joint-centre deviation
// with fewer markers, and joint-centre error against synthetic truth. Every
// evaluation tracks through the daemon's Tracker (same targets, priorities
// and solver settings as fabrikd), so the numbers are the daemon's numbers.
// Results are values (metres); tables and JSON are formatted separately.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::eval {

// `fabrik calibrate` in memory: template + static trial -> the daemon config
// (loaded exactly as fabrikd would load the written file).
DaemonConfig calibrate_config(const std::string& template_path, const std::string& static_path);

// The points a joint-centre comparison looks at: every joint (Model::joints)
// and every end site (wrist, toe tip, head top), by model point index.
struct ReferencePoints {
  std::vector<int> points;
  std::vector<std::string> names;
  std::vector<std::string> groups;  // name without its side prefix: "r_knee" -> "knee"
};
ReferencePoints reference_points(const Model& model);

// ---- walk: marker residuals on a recorded trial ----

struct MarkerStats {
  std::string marker, segment;
  double rms_m = 0.0, max_m = 0.0;
  int samples = 0;
};

struct WalkReport {
  double rate_hz = 0.0;
  std::vector<double> rms_m, max_m;  // per frame, over measured markers
  std::vector<std::string> worst;    // per frame
  // Per frame, the worst marker residual of an unconstrained rigid fit of
  // each segment's calibrated markers alone (no joints): what the data's own
  // non-rigidity (skin, shoe, marker glitches) leaves for any rigid segment.
  std::vector<double> cluster_max_m;
  std::vector<std::string> cluster_worst;
  double rms_mean_m = 0.0, rms_worst_m = 0.0;
  double max_m_over_frames = 0.0;
  std::size_t max_frame = 0;
  std::string max_marker;
  double cluster_max_over_frames_m = 0.0;
  std::size_t cluster_max_frame = 0;
  std::string cluster_max_marker;
  double iterations_mean = 0.0;
  std::vector<MarkerStats> markers;  // the tracker's marker order
};

WalkReport eval_walk(const DaemonConfig& config, const io::MarkerTrial& trial);
std::string walk_table(const WalkReport& r);
nlohmann::json walk_json(const WalkReport& r);
// frame,time_s,rms_mm,max_mm,worst_marker,cluster_max_mm,cluster_worst_marker
void write_walk_csv(const std::string& path, const WalkReport& r);

// ---- gaps: withhold one marker for a window, compare the model's position ----

struct GapOptions {
  std::vector<double> windows_s{0.5, 1.0};
  double stride_s = 0.5;             // window starts: 0, stride, 2 stride, ... (within the trial)
  std::vector<std::string> markers;  // withheld in turn; empty: every tracked marker in the trial
};

struct GapStats {
  std::string marker;
  double window_s = 0.0;
  int windows = 0, samples = 0;
  double rms_m = 0.0, max_m = 0.0;              // predicted vs withheld real position
  double joint_rms_m = 0.0, joint_max_m = 0.0;  // reference points vs the all-markers solution
};

struct GapSummary {
  double window_s = 0.0;
  int markers = 0, windows = 0;
  double median_rms_m = 0.0, median_max_m = 0.0, worst_rms_m = 0.0;
  std::string worst_marker;
  double joint_rms_m = 0.0, joint_max_m = 0.0;  // over all gaps
};

// One withheld window: the real (measured) and predicted (model) positions.
struct GapTrace {
  std::string marker;
  double window_s = 0.0;
  int first_frame = 0;  // frame index
  std::vector<Eigen::Vector3d> real_m, predicted_m;
};

struct GapReport {
  double rate_hz = 0.0;
  std::vector<GapStats> rows;  // per marker and window length
  std::vector<GapSummary> summary;
  std::vector<GapTrace> traces;
};

GapReport eval_gaps(const DaemonConfig& config, const io::MarkerTrial& trial,
                    const GapOptions& options = {});
std::string gaps_table(const GapReport& r);
nlohmann::json gaps_json(const GapReport& r);
// marker,window_s,start_frame,frame,time_s,real_{x,y,z}_mm,pred_{x,y,z}_mm,error_mm
void write_gaps_csv(const std::string& path, const GapReport& r);

// ---- reduction: fewer markers, joint centres against the full set ----

struct DropSet {
  std::string name;
  std::vector<std::string> markers;  // tracked markers left out for the whole trial
};

// Marker subsets for gait2354 (subject01): one marker of each thigh and shank
// cluster, the arms down to the wrists, the thigh clusters, the head, and a
// minimal set.
std::vector<DropSet> gait2354_drop_sets();

struct GroupDeviation {
  std::string group;
  double rms_m = 0.0, max_m = 0.0;
};

struct ReductionRow {
  std::string name;
  int dropped = 0, kept = 0;
  double rms_m = 0.0, max_m = 0.0;  // over every reference point and frame
  std::string max_point;
  double marker_rms_mean_m = 0.0;  // residual of the kept markers
  std::vector<GroupDeviation> groups;
};

// Throws std::invalid_argument if a drop set names a marker that is not tracked.
std::vector<ReductionRow> eval_reduction(const DaemonConfig& config, const io::MarkerTrial& trial,
                                         const std::vector<DropSet>& sets);
std::string reduction_table(const std::vector<ReductionRow>& rows);
nlohmann::json reduction_json(const std::vector<ReductionRow>& rows);

// ---- synthetic: joint centres against the truth ----

struct SyntheticOptions {
  std::vector<double> noise_mm{0.0, 1.0, 3.0};  // per axis, Gaussian
  double seconds = 10.0;
  double rate_hz = 100.0;
  unsigned seed = 1;
};

struct SyntheticRow {
  double noise_mm = 0.0;
  std::size_t frames = 0;
  double joint_rms_m = 0.0, joint_p99_m = 0.0, joint_max_m = 0.0;  // joints vs truth
  double marker_rms_mean_m = 0.0;
};

std::vector<SyntheticRow> eval_synthetic(const DaemonConfig& config,
                                         const SyntheticOptions& options = {});
std::string synthetic_table(const std::vector<SyntheticRow>& rows);
nlohmann::json synthetic_json(const std::vector<SyntheticRow>& rows);

}  // namespace fabrik::eval
