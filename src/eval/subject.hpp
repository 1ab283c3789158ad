// The recorded subject of an evaluation: its config calibrated from a static
// trial as `fabrik calibrate` would write it, the trial columns of its
// markers, and the points a joint-centre comparison looks at.
#pragma once

#include <string>
#include <vector>

#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::eval {

// `fabrik calibrate` in memory: template + static trial -> the daemon config
// (loaded exactly as fabrikd would load the written file).
DaemonConfig calibrate_config(const std::string& template_path, const std::string& static_path);

// The points a joint-centre comparison looks at: every joint (Model::joints)
// and every end site (wrist, toe tip, head top), by model point index.
struct ReferencePoints {
  std::vector<int> points;
  std::vector<std::string> names;
  std::vector<std::string> groups;  // name without its side prefix: "r_knee" -> "knee"
};
ReferencePoints reference_points(const Model& model);

// Trial column of each tracked marker, -1 if the trial lacks it.
std::vector<int> trial_columns(const DaemonConfig& config, const io::MarkerTrial& trial);

}  // namespace fabrik::eval
