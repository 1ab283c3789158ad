#include "gaps.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "distance_stats.hpp"
#include "tracking_run.hpp"

namespace fabrik::eval {

GapReport eval_gaps(const DaemonConfig& config, const io::MarkerTrial& trial,
                    const GapOptions& options) {
  const auto& markers = config.tracker.markers;
  const std::vector<int> col = trial_columns(config, trial);
  const ReferencePoints refs = reference_points(*config.tracker.model);
  const std::size_t frames = trial.frames();
  const TrackingRun full = track_withholding(config, trial, col, refs, frames, [](std::size_t, int) { return false; });

  std::vector<int> withheld;
  if (options.markers.empty()) {
    for (std::size_t i = 0; i < markers.size(); ++i)
      if (col[i] >= 0) withheld.push_back(static_cast<int>(i));
  } else {
    for (const std::string& name : options.markers) {
      int found = -1;
      for (std::size_t i = 0; i < markers.size(); ++i)
        if (markers[i].marker == name && col[i] >= 0) found = static_cast<int>(i);
      if (found < 0)
        throw std::invalid_argument("gaps: '" + name + "' is not a tracked marker of the trial");
      withheld.push_back(found);
    }
  }

  GapReport report;
  report.rate_hz = trial.rate_hz;
  const auto stride =
      static_cast<std::size_t>(std::max(1.0, std::round(options.stride_s * trial.rate_hz)));
  for (double window_s : options.windows_s) {
    const auto len = static_cast<std::size_t>(std::round(window_s * trial.rate_hz));
    if (len < 1 || len > frames) continue;
    GapSummary sum;
    sum.window_s = window_s;
    DistanceStats all_joints;
    std::vector<double> rms, maxes;
    for (int i : withheld) {
      GapStats row;
      row.marker = markers[i].marker;
      row.window_s = window_s;
      DistanceStats err, joints;
      for (std::size_t start = 0; start + len <= frames; start += stride) {
        const std::size_t end = start + len;
        // Frames after the gap cannot change what was predicted inside it.
        const TrackingRun run = track_withholding(config, trial, col, refs, end, [&](std::size_t f, int m) {
          return m == i && f >= start && f < end;
        });
        GapTrace trace{row.marker, window_s, static_cast<int>(start), {}, {}};
        for (std::size_t f = start; f < end; ++f) {
          const Eigen::Vector3d& real = trial.at(f, col[i]);
          if (!real.allFinite()) continue;  // a real gap: nothing to compare with
          const Eigen::Vector3d& pred = run.markers_m[f * run.n + i];
          err.add((pred - real).norm());
          trace.real_m.push_back(real);
          trace.predicted_m.push_back(pred);
          for (std::size_t p = 0; p < run.refs; ++p) {
            const double d = (run.ref_m[f * run.refs + p] - full.ref_m[f * full.refs + p]).norm();
            joints.add(d);
            all_joints.add(d);
          }
        }
        ++row.windows;
        report.traces.push_back(std::move(trace));
      }
      row.samples = err.n;
      row.rms_m = err.rms();
      row.max_m = err.max;
      row.joint_rms_m = joints.rms();
      row.joint_max_m = joints.max;
      if (row.samples == 0) continue;
      rms.push_back(row.rms_m);
      maxes.push_back(row.max_m);
      if (row.rms_m > sum.worst_rms_m) sum.worst_rms_m = row.rms_m, sum.worst_marker = row.marker;
      sum.windows += row.windows;
      report.rows.push_back(row);
    }
    sum.markers = static_cast<int>(rms.size());
    sum.median_rms_m = median(rms);
    sum.median_max_m = median(maxes);
    sum.joint_rms_m = all_joints.rms();
    sum.joint_max_m = all_joints.max;
    report.summary.push_back(sum);
  }
  return report;
}

}  // namespace fabrik::eval
