#include "offline/marker_match.hpp"

#include <algorithm>
#include <cstdio>
#include <numeric>
#include <stdexcept>

#include "offline/subject_markers.hpp"

namespace fabrik {

namespace {

// Whether the trial's column `c` (-1: none) holds a measured sample in any frame.
bool has_sample(const io::MarkerTrial& trial, int c) {
  for (std::size_t f = 0; c >= 0 && f < trial.frames(); ++f)
    if (trial.at(f, static_cast<std::size_t>(c)).allFinite()) return true;
  return false;
}

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
  // A label whose column holds no sample counts as missing: 25 of 41 markers blanked under
  // their labels passed as "ok" and "good" with no pelvis and no legs.
  std::vector<std::string> absent, unused, empty;
  std::size_t zero_columns = 0;  // of the empty ones, columns of exact (0, 0, 0) read as missing
  const std::vector<std::size_t>& zeros = trial.source.zero_samples;
  for (const std::string& name : names) {
    const int c = trial.find(name);
    const bool sampled = has_sample(trial, c);
    if (c < 0) absent.push_back(name);
    if (c < 0 || sampled) continue;
    empty.push_back(name);
    const auto k = static_cast<std::size_t>(c);
    zero_columns += k < zeros.size() && zeros[k] > 0 ? 1 : 0;
  }
  const std::size_t shared = names.size() - absent.size() - empty.size();
  // None with a sample: require_measured_marker says why (a unit, zeros), which this cannot.
  if (shared == 0 || 2 * shared >= names.size()) return;
  for (const std::string& label : trial.labels)
    if (std::find(names.begin(), names.end(), label) == names.end()) unused.push_back(label);
  const std::string count = std::to_string(shared) + " of the " + std::to_string(names.size());
  const std::string keep =
      "; to track with the " + std::to_string(shared) + " markers it has, give " + allow_option;
  if (absent.empty()) {  // the labels are the config's: their columns are empty
    throw std::runtime_error(
        trial_path + ": has samples for only " + count + " markers of the config " + config_file +
        " (fewer than half): the columns of " + std::to_string(empty.size()) +
        " of its labels hold none (" + name_list(empty, 8) + ")" +
        (zero_columns ? "; " + std::to_string(zero_columns) +
                            " of them hold exact (0, 0, 0) samples, read as missing"
                      : std::string()) +
        ". Tracking it would fit the model to those " + std::to_string(shared) +
        " and report a small residual for them.\nFix: check the trial's export (those markers "
        "were not measured, or not exported)" +
        (zero_columns ? std::string(", or keep the zeros as positions (the keep-zeros option)")
                      : std::string()) +
        keep);
  }
  throw std::runtime_error(
      trial_path + ": has only " + count + " marker names of the config " + config_file +
      (empty.empty() ? std::string()
                     : " with a sample (" + std::to_string(empty.size()) +
                           " more are columns without one: " + name_list(empty, 8) + ")") +
      " (fewer than half); tracking it would fit the model to those " + std::to_string(shared) +
      " and report a small residual for them." + names_beside(absent, "file:  ", unused) +
      "\nFix: " + kConfigFix + keep);
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

void require_measured_marker(const DaemonConfig& config, const io::MarkerTrial& trial,
                             const std::string& trial_path, std::size_t implausible,
                             const std::string& keep_zeros_option) {
  for (const MarkerTarget& target : config.tracker.markers)
    if (has_sample(trial, trial.find(target.marker))) return;
  std::string why = "every sample of them is empty";
  std::string fix = "check that the trial holds this subject's markers";
  if (implausible > 0) {
    char limit_mm[32];
    std::snprintf(limit_mm, sizeof limit_mm, "%g", config.max_abs_coordinate_m * 1e3);
    why = std::to_string(implausible) + " samples were farther than input.max_abs_coordinate_mm (" +
          limit_mm + " mm) from the origin";
    fix = "check the file's unit (it says '" + trial.source.units +
          "'): a file in mm labelled m is 1000 times too large";
  } else if (const std::size_t zeros =
                 std::accumulate(trial.source.zero_samples.begin(), trial.source.zero_samples.end(),
                                 std::size_t{0});
             zeros > 0) {
    why = std::to_string(zeros) + " samples are exactly (0, 0, 0), which is read as missing";
    fix = "if (0, 0, 0) is a measurement in this file, give " + keep_zeros_option;
  }
  throw std::runtime_error(trial_path + ": no tracked marker is measured in any of the " +
                           std::to_string(trial.frames()) + " frames: " + why + ". Fix: " + fix);
}

}  // namespace fabrik
