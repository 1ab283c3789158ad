// `fabrik synth`: a synthetic marker recording of a daemon config's model (smooth motion,
// Gaussian marker noise, occlusion gaps) with the true joint centres in a sidecar TRC, so
// replays through fabrikd can be checked for accuracy.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "io/marker_trial.hpp"
#include "solver/model.hpp"

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
};

// Throws std::invalid_argument when the options cannot be met (e.g. more gaps than fit).
SynthTrial make_synth_trial(const SynthSetup& setup, const SynthOptions& options);

// "walk.trc" -> "walk.joints.trc" (any other name gets ".joints.trc" appended).
std::string joints_sidecar_path(const std::string& trc_path);

}  // namespace fabrik::tools
