// Track a TRC recording with a daemon config (e.g. one `fabrik calibrate` wrote): the Tracker
// in your own loop, as a treadmill controller or a VR plugin would run it per frame.
//
//   track_trc CONFIG.json TRIAL.trc
#include <fabrik/config/load.hpp>
#include <fabrik/io/marker_trial.hpp>
#include <fabrik/tracking/tracker.hpp>

#include <cmath>
#include <cstdio>
#include <exception>
#include <vector>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s CONFIG.json TRIAL.trc\n", argv[0]);
    return 2;
  }
  fabrik::TrackerSetup setup;
  fabrik::io::MarkerTrial trial;
  try {
    setup = fabrik::load_tracker_setup_file(argv[1]);
    trial = fabrik::io::read_trc(argv[2]);  // metres, NaN where a marker is missing
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
  fabrik::Tracker tracker(setup);

  // The trial's column of each of the tracker's markers (-1: not in the file, occluded).
  std::vector<int> column;
  for (const fabrik::MarkerTarget& m : tracker.setup().markers) column.push_back(trial.find(m.marker));

  std::vector<Eigen::Vector3d> measured_world_m(column.size());
  std::vector<std::uint8_t> visible(column.size());
  double residual_sum_m = 0.0;
  int good = 0, solved = 0;
  for (std::size_t f = 0; f < trial.frames(); ++f) {
    for (std::size_t i = 0; i < column.size(); ++i) {
      visible[i] = column[i] >= 0 ? 1 : 0;
      measured_world_m[i] = column[i] >= 0 ? trial.at(f, static_cast<std::size_t>(column[i]))
                                           : Eigen::Vector3d::Zero();
    }
    const fabrik::TrackResult& r = tracker.track(trial.time_s(f), measured_world_m, visible);
    if (r.residual_count == 0) continue;
    ++solved;
    residual_sum_m += r.residual_rms_m;
    if (r.quality == fabrik::FitQuality::good) ++good;
  }
  const fabrik::Model& model = tracker.model();
  std::printf("%zu frames, %d solved, %d of good quality, mean residual rms %.2f mm\n",
              trial.frames(), solved, good, solved ? residual_sum_m / solved * 1e3 : 0.0);
  // The last frame's coordinates, OpenSim-named (radians for rotations, metres for translations).
  const fabrik::TrackResult& last = tracker.track(trial.time_s(trial.frames() - 1),
                                                  measured_world_m, visible);
  for (std::size_t c = 0; c < model.coordinates.size() && c < 4; ++c)
    std::printf("  %s = %.4f\n", model.coordinates[c].name.c_str(), last.coordinates[c]);
  return solved == static_cast<int>(trial.frames()) && good * 10 >= solved * 9 ? 0 : 1;
}
