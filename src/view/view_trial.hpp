// `fabrik view --trial`: a recording tracked offline (solve_trial, the path of `fabrik solve`),
// every frame encoded as the pose the daemon would publish, served as one `trial` message.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::view {


struct TrialView {
  std::string message;  // {"topic": "trial", "data": {"model": ..., "poses": [...], "file"}}
  std::size_t poses = 0;
};

// Tracks `trial` with `config`; the poses are JSON in the config's output units, at the file's
// own times, with `measured` when the config asks for it (output.measured_markers).
// `file_name` (may be empty) is the message's "file", shown by the page.
TrialView trial_view(const DaemonConfig& config, const io::MarkerTrial& trial,
                     const std::string& file_name = "");

}  // namespace fabrik::view
