#include "reduction.hpp"

#include <algorithm>
#include <cstdint>
#include <map>
#include <stdexcept>

#include "distance_stats.hpp"
#include "tracking_run.hpp"

namespace fabrik::eval {

std::vector<DropSet> gait2354_drop_sets() {
  return {
      {"none (full set)", {}},
      {"one per thigh/shank cluster",
       {"R.Thigh.Rear", "L.Thigh.Rear", "R.Shank.Rear", "L.Shank.Rear"}},
      {"arms: wrists only", {"R.Bicep", "R.Elbow", "L.Bicep", "L.Elbow"}},
      {"no thigh clusters",
       {"R.Thigh.Upper", "R.Thigh.Front", "R.Thigh.Rear", "L.Thigh.Upper", "L.Thigh.Front",
        "L.Thigh.Rear"}},
      {"no head", {"R.Temple", "L.Temple", "Top.Head"}},
      {"one foot marker fewer", {"R.Midfoot.Lat", "L.Midfoot.Lat"}},
      // Two markers per limb segment (three on the pelvis and feet), one per wrist, no head.
      {"minimal (26 of 41)",
       {"R.Temple", "L.Temple", "Top.Head", "R.Bicep", "L.Bicep", "R.Wrist.Med", "L.Wrist.Med",
        "R.Thigh.Rear", "L.Thigh.Rear", "R.Shank.Rear", "L.Shank.Rear", "R.Midfoot.Lat",
        "L.Midfoot.Lat", "R.Toe.Med", "L.Toe.Med"}},
  };
}

std::vector<ReductionRow> eval_reduction(const DaemonConfig& config, const io::MarkerTrial& trial,
                                         const std::vector<DropSet>& sets) {
  const auto& markers = config.tracker.markers;
  const std::vector<int> col = trial_columns(config, trial);
  const ReferencePoints refs = reference_points(*config.tracker.model);
  const std::size_t frames = trial.frames();
  const TrackingRun full = track_withholding(config, trial, col, refs, frames, [](std::size_t, int) { return false; });
  int present = 0;
  for (int c : col) present += c >= 0 ? 1 : 0;
  std::vector<ReductionRow> rows;
  for (const DropSet& set : sets) {
    std::vector<std::uint8_t> drop(markers.size(), 0);
    for (const std::string& name : set.markers) {
      const auto it = std::find_if(markers.begin(), markers.end(),
                                   [&](const MarkerTarget& m) { return m.marker == name; });
      if (it == markers.end())
        throw std::invalid_argument("reduction '" + set.name + "': '" + name +
                                    "' is not a tracked marker");
      drop[it - markers.begin()] = 1;
    }
    const TrackingRun run =
        track_withholding(config, trial, col, refs, frames, [&](std::size_t, int m) { return drop[m] != 0; });
    ReductionRow row;
    row.name = set.name;
    row.dropped = static_cast<int>(set.markers.size());
    row.kept = present - row.dropped;
    DistanceStats all;
    std::map<std::string, DistanceStats> groups;
    std::vector<std::string> order;
    for (std::size_t f = 0; f < frames; ++f) {
      row.marker_rms_mean_m += run.rms_m[f] / static_cast<double>(frames);
      for (std::size_t p = 0; p < run.refs; ++p) {
        const double d = (run.ref_m[f * run.refs + p] - full.ref_m[f * full.refs + p]).norm();
        all.add(d, refs.names[p]);
        if (!groups.count(refs.groups[p])) order.push_back(refs.groups[p]);
        groups[refs.groups[p]].add(d);
      }
    }
    row.rms_m = all.rms();
    row.max_m = all.max;
    row.max_point = all.max_name;
    for (const std::string& g : order) row.groups.push_back({g, groups[g].rms(), groups[g].max});
    rows.push_back(row);
  }
  return rows;
}

}  // namespace fabrik::eval
