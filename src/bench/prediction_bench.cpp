// `fabrik bench fullbody`, gap prediction: the same synthetic motion through
// the Tracker with a moving occlusion (each segment's markers hidden in turn
// for 0.5 s), once without and once with prediction, the two trackers
// interleaved frame by frame (in alternating order) so both see the same
// machine load.
#include <chrono>

#include "bench.hpp"
#include "stats.hpp"
#include "synth/synthetic_motion.hpp"
#include "tracking/tracker.hpp"

namespace fabrik::bench {

nlohmann::json run_prediction_comparison(const std::shared_ptr<const Model>& model,
                                         const FullbodyOptions& options, const SolverOptions& o) {
  const Model& m = *model;
  TrackerSetup setup;
  setup.model = model;
  const std::vector<int> points = m.marker_points();
  for (int p : points) setup.markers.push_back({m.points[p].name, p, 0, 1.0});
  setup.solver = o;
  setup.prediction.enabled = false;
  setup.prediction.level = 0;  // the markers' level, as the daemon config's default
  Tracker without(setup);
  setup.prediction.enabled = true;
  Tracker with(setup);
  MotionSettings ms;
  ms.seed = options.seed;
  SyntheticMotion motion(m, ms);
  Posture truth = Posture::rest(m);
  std::vector<Eigen::Vector3d> measured(points.size());
  std::vector<std::uint8_t> visible(points.size(), 1);
  std::vector<double> without_us, with_us, track_without_us, track_with_us;
  double iterations_without = 0.0, iterations_with = 0.0;
  const int hide_frames = std::max(1, static_cast<int>(0.5 * options.rate_hz));
  for (int f = 0; f < options.frames; ++f) {
    const double t_s = f / options.rate_hz;
    motion.posture_at(t_s, truth);
    motion.sample(truth, points, options.noise_mm * 1e-3, measured);
    const int hidden = (f / hide_frames) % static_cast<int>(m.segments.size());
    for (std::size_t i = 0; i < points.size(); ++i)
      visible[i] = m.points[points[i]].segment == hidden ? 0 : 1;
    Tracker* order[2] = {&without, &with};
    if (f % 2) std::swap(order[0], order[1]);
    for (Tracker* t : order) {
      const auto t0 = std::chrono::steady_clock::now();
      const TrackResult& r = t->track(t_s, measured, visible);
      const double track_us =
          std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
      if (f > 0) {
        (t == &with ? with_us : without_us).push_back(r.solve_us);
        (t == &with ? track_with_us : track_without_us).push_back(track_us);
      }
      (t == &with ? iterations_with : iterations_without) += r.solve.iterations;
    }
  }
  const double a = quantile(without_us, 0.5), b = quantile(with_us, 0.5);
  return {{"occlusion", "each segment's markers hidden in turn for 0.5 s"},
          {"solve_us_median_without", a},
          {"solve_us_median_with", b},
          {"iterations_mean_without", iterations_without / options.frames},
          {"iterations_mean_with", iterations_with / options.frames},
          {"ratio", a > 0.0 ? b / a : 0.0},
          // The whole Tracker::track call, the donor choice included.
          {"track_us_median_without", quantile(track_without_us, 0.5)},
          {"track_us_median_with", quantile(track_with_us, 0.5)},
          {"track_us_p99_without", quantile(track_without_us, 0.99)},
          {"track_us_p99_with", quantile(track_with_us, 0.99)},
          {"track_us_max_without", quantile(track_without_us, 1.0)},
          {"track_us_max_with", quantile(track_with_us, 1.0)}};
}

}  // namespace fabrik::bench
