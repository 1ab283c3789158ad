#include "prefilter.hpp"

#include <limits>
#include <vector>

#include "solve_trial.hpp"
#include "trajectory_filter.hpp"

namespace fabrik {

std::size_t drop_left_out_then_filter(const DaemonConfig& config, io::MarkerTrial& trial,
                                      double cutoff_hz) {
  std::size_t changed = 0;
  if (trial.markers() > 0) {
    // Tracker marker -> trial column (-1: the trial lacks it).
    std::vector<int> column;
    for (const MarkerTarget& m : config.tracker.markers) column.push_back(trial.find(m.marker));
    const io::MarkerTrial recorded = trial;
    const Eigen::Vector3d gap = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    solve_trial(
        config, recorded, {}, nullptr,
        [&](std::size_t f, double, const Tracker&, const TrackResult& r) {
          for (std::size_t i = 0; i < column.size() && i < r.outliers.size(); ++i) {
            const int j = column[i];
            const int from = r.relabelled_from[i];
            if (j < 0 || (!r.outliers[i] && from < 0)) continue;
            const int from_column = from >= 0 ? column[static_cast<std::size_t>(from)] : -1;
            // A swapped label takes the sample it was solved with; a left-out one is a gap.
            trial.at(f, static_cast<std::size_t>(j)) =
                from_column >= 0 ? recorded.at(f, static_cast<std::size_t>(from_column)) : gap;
            ++changed;
          }
        },
        TrialPass::live);  // only the outlier flags are used
  }
  filtfilt_trial(trial, cutoff_hz);
  return changed;
}

}  // namespace fabrik
