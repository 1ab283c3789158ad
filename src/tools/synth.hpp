// `fabrik synth`: a synthetic marker recording of a daemon config's model (smooth motion,
// Gaussian marker noise, occlusion gaps) with the true joint centres in a sidecar TRC, so
// replays through fabrikd can be checked for accuracy.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"
#include "solver/model.hpp"
#include "synth/keypoint_corruption.hpp"

namespace fabrik::tools {

// The model and the tracked stream markers of a daemon config (fabrikd-config/1).
struct SynthSetup {
  std::shared_ptr<const Model> model;
  std::vector<std::string> marker_names;  // stream names
  std::vector<int> marker_points;         // per stream name: index into Model::points
};
// Through the daemon's own loader, so the names are exactly what fabrikd tracks. Throws
// ConfigError naming the file, the JSON pointer and the fix.
SynthSetup load_synth_setup(const std::string& config_path);
SynthSetup synth_setup(const DaemonConfig& config);

struct SynthOptions {
  double seconds = 10.0;
  double rate_hz = 100.0;
  double noise_mm = 1.0;  // standard deviation per axis
  int gaps = 0;           // occlusion windows of 0.2-1 s, on random markers, never overlapping
  unsigned seed = 1;
};

struct GapWindow {
  int marker = 0;       // index into the trial's labels
  int first_frame = 0;  // frame indices [first_frame, first_frame + frames)
  int frames = 0;
};

struct SynthTrial {
  io::MarkerTrial markers;  // metres, NaN inside gaps
  io::MarkerTrial joints;   // true joint centres, no noise, no gaps
  std::vector<GapWindow> gaps;
  // The true named coordinates (Model::coordinates), per frame [frame * names + c]:
  // radians (continuous over frames) or metres.
  std::vector<std::string> coordinate_names;
  std::vector<std::uint8_t> coordinate_is_rotation;
  std::vector<double> coordinates;
};

// Throws std::invalid_argument when the options cannot be met (e.g. more gaps than fit).
SynthTrial make_synth_trial(const SynthSetup& setup, const SynthOptions& options);

// A markerless trial (docs/keypoints.md): the config's markers are keypoints on joint
// centres and segment points (a keypoint template calibrated with --nominal); the exact
// keypoints of the synthetic motion get jitter, dropouts and left/right swaps.
struct KeypointTrial {
  SynthTrial truth;                  // exact keypoints, true joint centres and coordinates
  io::MarkerTrial keypoints;         // what a markerless pipeline would write
  std::vector<InjectedRun> injected;  // every swap and dropout, in frames
};
KeypointTrial make_keypoint_trial(const SynthSetup& setup, const SynthOptions& options,
                                  const KeypointCorruption& corruption);
// One line per injected frame: frame (the TRC's Frame#), time_s, kind, keypoints.
void write_injected_csv(const std::string& path, const KeypointTrial& trial);
// The true coordinates as an OpenSim Coordinates table (.mot, degrees).
void write_truth_mot(const std::string& path, const SynthTrial& trial);

// "walk.trc" -> "walk": the name the files synth writes beside a trial share (any other
// name is its own stem).
std::string sidecar_stem(const std::string& trc_path);
// "walk.trc" -> "walk.joints.trc" (any other name gets ".joints.trc" appended).
std::string joints_sidecar_path(const std::string& trc_path);

}  // namespace fabrik::tools
