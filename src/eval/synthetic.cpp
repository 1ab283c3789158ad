#include "synthetic.hpp"

#include <cstdint>

#include "common/quantile.hpp"
#include "distance_stats.hpp"
#include "synth/synthetic_motion.hpp"
#include "tracking/tracker.hpp"

namespace fabrik::eval {

std::vector<SyntheticRow> eval_synthetic(const DaemonConfig& config,
                                         const SyntheticOptions& options) {
  const Model& model = *config.tracker.model;
  const auto& markers = config.tracker.markers;
  std::vector<int> points;
  for (const MarkerTarget& m : markers) points.push_back(m.point);
  const auto frames = static_cast<std::size_t>(options.seconds * options.rate_hz);
  std::vector<SyntheticRow> rows;
  for (double noise_mm : options.noise_mm) {
    // Same seed for every noise level: the same motion, only the noise differs.
    MotionSettings settings;
    settings.seed = options.seed;
    SyntheticMotion motion(model, settings);
    Tracker tracker(config.tracker);
    Posture truth = Posture::rest(model);
    std::vector<Eigen::Vector3d> measured(points.size());
    const std::vector<std::uint8_t> visible(points.size(), 1);
    std::vector<double> errors;
    SyntheticRow row;
    row.noise_mm = noise_mm;
    row.frames = frames;
    DistanceStats acc;
    for (std::size_t f = 0; f < frames; ++f) {
      const double t = static_cast<double>(f) / options.rate_hz;
      motion.posture_at(t, truth);
      motion.sample(truth, points, noise_mm * 1e-3, measured);
      const TrackResult& r = tracker.track(t, measured, visible);
      row.marker_rms_mean_m += r.residual_rms_m / static_cast<double>(frames);
      for (std::size_t j = 0; j < model.joints.size(); ++j) {
        const double e =
            (r.joints_world_m[j] - truth.point_world_m(model, model.joints[j].point)).norm();
        errors.push_back(e);
        acc.add(e);
      }
    }
    row.joint_rms_m = acc.rms();
    row.joint_max_m = acc.max;
    row.joint_p99_m = quantile(errors, 0.99);
    rows.push_back(row);
  }
  return rows;
}

}  // namespace fabrik::eval
