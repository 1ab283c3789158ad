#include "read_recording.hpp"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

#include "common/format_number.hpp"
#include "common/safe_text.hpp"

namespace fabrik::apps {

void print_warnings(const std::string& command, const std::string& path,
                    const std::vector<std::string>& warnings) {
  for (const std::string& w : warnings) {
    // Paths are as the user gave them, warnings quote the file's own bytes.
    std::fprintf(stderr, "fabrik %s: warning: %s: %s\n", command.c_str(), safe_lines(path).c_str(),
                 safe_lines(w).c_str());
  }
}

std::string name_list(const std::vector<std::string>& names) {
  std::string s;
  for (std::size_t i = 0; i < names.size() && i < 12; ++i) s += (i ? ", " : "") + names[i];
  return s + (names.size() > 12 ? ", ..." : "");
}

io::MarkerTrial read_trial_or_explain(const std::string& command, const std::string& path,
                                      bool keep_zeros) {
  io::MarkerTrial trial = io::read_trial(path, {.zeros_are_missing = !keep_zeros});
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
                             name_list(names) + "\n  file:   " + name_list(table.sensors) +
                             "\nFix: use a config calibrated for these sensors");
  return table;
}

void require_time_overlap(const std::string& command, const io::MarkerTrial& trial,
                          const std::string& trial_path, const io::OrientationTable& table,
                          const std::string& table_path) {
  const std::size_t frames = trial.frames();
  if (frames == 0 || table.rows() == 0) return;
  std::size_t outside = 0;
  for (std::size_t f = 0; f < frames; ++f)
    if (!table.covers(trial.file_time_s(f))) ++outside;
  if (outside == 0) return;
  const auto span = [](double first_s, double last_s) {
    return format_number("%.9g", first_s) + " to " + format_number("%.9g", last_s) + " s";
  };
  const std::string spans = "the markers (" + trial_path + ") span " +
                            span(trial.file_time_s(0), trial.file_time_s(frames - 1)) +
                            ", the orientations " + span(table.time_s.front(), table.time_s.back());
  // Joined on time, a table beside the trial would leave every frame without orientations:
  // a markers-only result that looks like a joined one.
  if (outside == frames)
    throw std::runtime_error(
        table_path + ": no marker frame falls within its time span: " + spans +
        ". Fix: give the orientations recorded with this trial, or make the table's time "
        "column count from the same start as the trial's (the two are joined on their times)");
  print_warnings(command, table_path,
                 {std::to_string(outside) + " of " + std::to_string(frames) +
                  " marker frames fall outside its time span (" + spans +
                  "): they are tracked without orientations"});
}

}  // namespace fabrik::apps
