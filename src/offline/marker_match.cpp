#include "offline/marker_match.hpp"

#include <stdexcept>

namespace fabrik {

void require_shared_markers(const DaemonConfig& config, const io::MarkerTrial& trial,
                            const std::string& trial_path) {
  std::vector<std::string> names;
  for (const MarkerTarget& m : config.tracker.markers) names.push_back(m.marker);
  for (const std::string& name : names) {
    if (trial.find(name) >= 0) return;
  }
  std::string message = trial_path + ": shares none of the " + std::to_string(names.size()) +
                        " marker names of the config " + config.file + " (" +
                        std::to_string(trial.markers()) + " labels in the file);" +
                        " tracking it would solve no frame." +
                        names_beside(names, "file:  ", trial.labels);
  message +=
      "\nFix: use a config made for this marker set (fabrik calibrate --template T --static S "
      "writes one), or rename the config's target markers to the file's labels";
  throw std::runtime_error(message);
}

}  // namespace fabrik
