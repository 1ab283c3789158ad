// Whether a config's marker names fit a trial's labels: a config that shares no name with a
// trial would track every frame with no targets and report a residual of 0 mm. Which labels
// come closest is config/closest_names.hpp (the daemon uses it too).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "config/closest_names.hpp"
#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"

namespace fabrik {

// Throws std::runtime_error when the trial shares none of the config's marker names (exactly,
// as the tracker matches them): the message lists the config's names beside the trial's
// labels, the closest matches, and the fix. `subject_option`: the caller's option that takes
// one subject of a `Subject:Marker` file (`fabrik solve --subject`; see given_option), offered
// where the labels differ by such a prefix only; empty where the caller has none.
// Unless `allow_few`, a trial with fewer than half of the config's names is refused too, the
// message naming the names missing, the closest labels and `allow_option`, the caller's option
// that lets it be tracked.
void require_shared_markers(const DaemonConfig& config, const io::MarkerTrial& trial,
                            const std::string& trial_path, const std::string& subject_option = {},
                            bool allow_few = true, const std::string& allow_option = {});

// Throws std::runtime_error when no tracked marker of the config has a sample in any frame (a
// summary, report and batch row of nothing would follow, and exit 0), saying why: every sample
// empty, exact zeros read as missing (`keep_zeros_option` keeps them), or `implausible`
// samples dropped beyond input.max_abs_coordinate_mm (a unit that is wrong).
void require_measured_marker(const DaemonConfig& config, const io::MarkerTrial& trial,
                             const std::string& trial_path, std::size_t implausible,
                             const std::string& keep_zeros_option);

}  // namespace fabrik
