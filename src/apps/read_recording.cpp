#include "read_recording.hpp"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

#include "common/safe_text.hpp"
#include "config/closest_names.hpp"

namespace fabrik::apps {

void print_warnings(const std::string& command, const std::string& path,
                    const std::vector<std::string>& warnings) {
  for (const std::string& w : warnings) {
    // Paths are as the user gave them, warnings quote the file's own bytes.
    std::fprintf(stderr, "fabrik %s: warning: %s: %s\n", command.c_str(), safe_lines(path).c_str(),
                 safe_lines(w).c_str());
  }
}

io::MarkerTrial read_trial_or_explain(const std::string& command, const std::string& path,
                                      bool keep_zeros) {
  io::MarkerTrial trial = io::read_trial(path, {.zeros_are_missing = !keep_zeros});
  // Markers a hundred metres apart are no person's: a solve would drop them as implausible
  // (or keep the few near the origin), a calibration would write thighs of 400 m. Markers a
  // few millimetres apart neither: a solve fitted them with a residual of 528 mm.
  if (!trial.source.unit_problem.empty()) {
    std::erase(trial.warnings, trial.source.unit_problem);  // said once, as the error
    print_warnings(command, path, trial.warnings);
    throw std::runtime_error(path + ": " + trial.source.unit_problem);
  }
  print_warnings(command, path, trial.warnings);
  io::require_marker_data(trial, path);
  return trial;
}

io::OrientationTable read_orientations_or_explain(const std::string& command,
                                                  const DaemonConfig& config,
                                                  const std::string& path) {
  io::OrientationTable table = io::read_orientation_table(path);
  print_warnings(command, path, table.warnings);
  const std::vector<SensorTarget>& sensors = config.tracker.sensors.sensors;
  if (sensors.empty())
    throw std::runtime_error(path + ": " + config.file +
                             " has no orientation sensors (\"sensors\"). Fix: calibrate a "
                             "template with \"sensors\" (fabrik calibrate --static-orientations)");
  std::vector<std::string> names;
  for (const SensorTarget& t : sensors) names.push_back(t.sensor);
  if (std::none_of(names.begin(), names.end(),
                   [&](const std::string& n) { return table.find(n) >= 0; }))
    throw std::runtime_error(path + ": shares none of the " + std::to_string(names.size()) +
                             " sensor names of " + config.file + ".\n  config: " +
                             name_list(names, 12) + "\n  file:   " + name_list(table.sensors, 12) +
                             "\nFix: use a config calibrated for these sensors");
  return table;
}

std::vector<std::string> time_overlap_warnings(const io::MarkerTrial& trial,
                                               const std::string& trial_path,
                                               const io::OrientationTable& table,
                                               const std::string& table_path) {
  std::vector<std::string> warnings;
  io::check_time_overlap(trial, trial_path, table, table_path, warnings);
  return warnings;
}

}  // namespace fabrik::apps
