#include "offline/marker_match.hpp"

#include <algorithm>
#include <stdexcept>

#include "offline/subject_markers.hpp"

namespace fabrik {

namespace {

// The fix of a trial whose names are not the config's.
constexpr const char* kConfigFix =
    "use a config made for this marker set (fabrik calibrate --template T --static S writes "
    "one), or map the file's labels onto the model's markers in the config's targets.markers, "
    "e.g. \"R_ASIS\": {\"point\": \"R.ASIS\"} (docs/daemon-config.md)";

// Fewer than half of the config's names in the trial: most likely another marker set or
// another spelling, whose few shared markers a solve would fit closely (a judgement: a
// lab that means it says so with the caller's option).
void require_most_markers(const std::vector<std::string>& names, const io::MarkerTrial& trial,
                          const std::string& trial_path, const std::string& config_file,
                          const std::string& allow_option) {
  std::vector<std::string> missing, unused;
  for (const std::string& name : names)
    if (trial.find(name) < 0) missing.push_back(name);
  const std::size_t shared = names.size() - missing.size();
  if (2 * shared >= names.size()) return;
  for (const std::string& label : trial.labels)
    if (std::find(names.begin(), names.end(), label) == names.end()) unused.push_back(label);
  throw std::runtime_error(
      trial_path + ": has only " + std::to_string(shared) + " of the " +
      std::to_string(names.size()) + " marker names of the config " + config_file +
      " (fewer than half); tracking it would fit the model to those " + std::to_string(shared) +
      " and report a small residual for them." + names_beside(missing, "file:  ", unused) +
      "\nFix: " + kConfigFix + "; to track with the " + std::to_string(shared) +
      " markers it has, give " + allow_option);
}

}  // namespace

void require_shared_markers(const DaemonConfig& config, const io::MarkerTrial& trial,
                            const std::string& trial_path, const std::string& subject_option,
                            bool allow_few, const std::string& allow_option) {
  std::vector<std::string> names;
  for (const MarkerTarget& m : config.tracker.markers) names.push_back(m.marker);
  for (const std::string& name : names) {
    if (trial.find(name) < 0) continue;
    if (!allow_few) require_most_markers(names, trial, trial_path, config.file, allow_option);
    return;
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
  message += "\nFix: " + std::string(kConfigFix);
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
