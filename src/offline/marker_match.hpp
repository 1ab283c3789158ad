// Whether a config's marker names fit a trial's labels, and which labels come closest when
// they do not: a config that shares no name with a trial would track every frame with no
// targets and report a residual of 0 mm.
#pragma once

#include <string>
#include <vector>

#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"

namespace fabrik {

struct NameMatch {
  std::string config_name;
  std::string trial_label;
  std::string how;  // "case", "after 'Subject:'", "punctuation", "2 edits"
};

// For each config name, the trial label closest to it, if any is close: the same name in
// another case, the same name after a `Subject:` prefix, or a spelling within a few edits
// (ignoring case and punctuation). Best matches first.
std::vector<NameMatch> closest_labels(const std::vector<std::string>& config_names,
                                      const std::vector<std::string>& trial_labels);

// Throws std::runtime_error when the trial shares none of the config's marker names (exactly,
// as the tracker matches them): the message lists the config's names beside the trial's
// labels, the closest matches, and the fix.
void require_shared_markers(const DaemonConfig& config, const io::MarkerTrial& trial,
                            const std::string& trial_path);

}  // namespace fabrik
