#include "read_recording.hpp"

#include <cstdio>

namespace fabrik::apps {

void print_warnings(const std::string& command, const std::string& path,
                    const std::vector<std::string>& warnings) {
  for (const std::string& w : warnings) {
    std::fprintf(stderr, "fabrik %s: warning: %s: %s\n", command.c_str(), path.c_str(), w.c_str());
  }
}

io::MarkerTrial read_trial_or_explain(const std::string& command, const std::string& path,
                                      bool keep_zeros) {
  io::MarkerTrial trial = io::read_trial(path, {.zeros_are_missing = !keep_zeros});
  print_warnings(command, path, trial.warnings);
  io::require_marker_data(trial, path);
  return trial;
}

}  // namespace fabrik::apps
