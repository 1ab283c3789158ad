#include "gaps.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>

#include "distance_stats.hpp"
#include "tracking/two_sided_fill.hpp"
#include "tracking_run.hpp"

namespace fabrik::eval {

const char* to_string(GapMode mode) { return mode == GapMode::live ? "live" : "offline"; }

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
  report.clock = trial.clock();
  const std::size_t n = markers.size();
  std::vector<double> times_s(frames);
  std::vector<Eigen::Vector3d> measured(frames * n, Eigen::Vector3d::Constant(NAN));
  std::vector<std::uint8_t> seen(frames * n, 0);
  for (std::size_t f = 0; f < frames; ++f) {
    times_s[f] = trial.time_s(f);
    for (std::size_t m = 0; m < n; ++m) {
      if (col[m] >= 0) measured[f * n + m] = trial.at(f, col[m]);
      seen[f * n + m] = measured[f * n + m].allFinite() ? 1 : 0;
    }
  }
  const auto stride =
      static_cast<std::size_t>(std::max(1.0, std::round(options.stride_s * trial.rate_hz)));
  for (GapMode mode : options.modes)
  for (double window_s : options.windows_s) {
    const auto len = static_cast<std::size_t>(std::round(window_s * trial.rate_hz));
    if (len < 1 || len > frames) continue;
    GapSummary sum;
    sum.mode = mode;
    sum.window_s = window_s;
    DistanceStats all_joints;
    std::vector<double> rms, maxes;
    for (int i : withheld) {
      GapStats row;
      row.marker = markers[i].marker;
      row.mode = mode;
      row.window_s = window_s;
      DistanceStats err, joints;
      for (std::size_t start = 0; start + len <= frames; start += stride) {
        const std::size_t end = start + len;
        const auto hidden = [&](std::size_t f, int m) { return m == i && f >= start && f < end; };
        std::vector<Eigen::Vector3d> predicted(len);
        if (mode == GapMode::live) {
          // Frames after the gap cannot change what was predicted inside it;
          // two more show the return.
          const std::size_t stop = std::min(frames, end + 2);
          const TrackingRun run = track_withholding(config, trial, col, refs, stop, hidden);
          for (std::size_t f = start; f < end; ++f) {
            predicted[f - start] = run.markers_m[f * run.n + i];
            if (!trial.at(f, col[i]).allFinite()) continue;
            for (std::size_t p = 0; p < run.refs; ++p) {
              const double d = (run.ref_m[f * run.refs + p] - full.ref_m[f * full.refs + p]).norm();
              joints.add(d);
              all_joints.add(d);
            }
          }
          if (end >= 2 && end + 1 < stop) {
            const auto step = [&](std::size_t f, std::size_t p) {
              return (run.ref_m[f * run.refs + p] - run.ref_m[(f - 1) * run.refs + p]).norm();
            };
            for (std::size_t p = 0; p < run.refs; ++p) {
              const double jump = step(end, p) - std::max(step(end - 1, p), step(end + 1, p));
              row.return_jump_m = std::max(row.return_jump_m, jump);
            }
          }
        } else {
          std::vector<std::uint8_t> visible = seen;
          for (std::size_t f = start; f < end; ++f) visible[f * n + i] = 0;
          const TwoSidedFill fill = fill_two_sided(config.tracker, times_s, measured, visible);
          for (std::size_t f = start; f < end; ++f) predicted[f - start] = fill.markers_m[f * n + i];
        }
        GapTrace trace{row.marker, mode, window_s, start, {}, {}};
        for (std::size_t f = start; f < end; ++f) {
          const Eigen::Vector3d& real = trial.at(f, col[i]);
          const Eigen::Vector3d& pred = predicted[f - start];
          if (!real.allFinite() || !pred.allFinite()) continue;  // nothing to compare
          err.add((pred - real).norm());
          trace.real_m.push_back(real);
          trace.predicted_m.push_back(pred);
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
      sum.return_jump_m = std::max(sum.return_jump_m, row.return_jump_m);
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
