#include "tracking_run.hpp"

#include <cmath>
#include <cstdint>

#include "tracking/tracker.hpp"

namespace fabrik::eval {

TrackingRun track_withholding(const DaemonConfig& config, const io::MarkerTrial& trial,
                              const std::vector<int>& col, const ReferencePoints& refs,
                              std::size_t frames,
                              const std::function<bool(std::size_t, int)>& hide) {
  Tracker tracker(config.tracker);
  const Model& model = tracker.model();
  const int n = tracker.marker_count();
  TrackingRun run;
  run.refs = refs.points.size();
  run.n = static_cast<std::size_t>(n);
  run.ref_m.reserve(frames * run.refs);
  run.markers_m.reserve(frames * run.n);
  std::vector<Eigen::Vector3d> measured(n);
  std::vector<std::uint8_t> visible(n);
  for (std::size_t f = 0; f < frames; ++f) {
    for (int i = 0; i < n; ++i) {
      measured[i] = col[i] >= 0 ? trial.at(f, col[i]) : Eigen::Vector3d::Constant(NAN);
      visible[i] = measured[i].allFinite() && !hide(f, i) ? 1 : 0;
    }
    const TrackResult& r = tracker.track(trial.time_s(f), measured, visible);
    for (int p : refs.points) run.ref_m.push_back(tracker.posture().point_world_m(model, p));
    run.markers_m.insert(run.markers_m.end(), r.markers_world_m.begin(), r.markers_world_m.end());
    run.rms_m.push_back(r.residual_rms_m);
  }
  return run;
}

}  // namespace fabrik::eval
