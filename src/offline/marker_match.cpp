#include "offline/marker_match.hpp"

#include <stdexcept>

#include "offline/subject_markers.hpp"

namespace fabrik {

void require_shared_markers(const DaemonConfig& config, const io::MarkerTrial& trial,
                            const std::string& trial_path, const std::string& subject_option) {
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
  // Where only a subject prefix stands between them, the fix that keeps the config.
  std::string file_prefix, config_prefix;
  for (const NameMatch& m : closest_labels(names, trial.labels)) {
    if (config_prefix.empty()) config_prefix = m.name_prefix;
    if (file_prefix.empty()) file_prefix = m.label_prefix;
  }
  message +=
      "\nFix: use a config made for this marker set (fabrik calibrate --template T --static S "
      "writes one), or rename the config's target markers to the file's labels";
  const std::string give_subject = given_option(
      subject_option, file_prefix.substr(0, file_prefix.empty() ? 0 : file_prefix.size() - 1));
  if (!file_prefix.empty() && config_prefix.empty() && !subject_option.empty())
    message += "; to track one subject of this file, give " + give_subject;
  if (!config_prefix.empty())
    message += " (the config's names carry the subject prefix '" + config_prefix +
               "': remove it from its targets" +
               (file_prefix.empty() || subject_option.empty() ? std::string()
                                                              : ", then give " + give_subject) +
               ", or calibrate from this subject's own file)";
  throw std::runtime_error(message);
}

}  // namespace fabrik
