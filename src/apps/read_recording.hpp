// How the `fabrik` commands that take a recording read it: every reader warning printed on
// stderr ("fabrik solve: warning: walk.trc: ..."), and a file without 3D marker data refused
// (FormatError, exit 2) with what it holds instead.
#pragma once

#include <string>
#include <vector>

#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"
#include "io/orientation_table.hpp"

namespace fabrik::apps {

io::MarkerTrial read_trial_or_explain(const std::string& command, const std::string& path,
                                      bool keep_zeros);

// An orientation table for `config`'s sensors, warnings printed; refused
// (runtime_error, exit 2) when the config has no sensors or the table shares
// none of their names.
io::OrientationTable read_orientations_or_explain(const std::string& command,
                                                  const DaemonConfig& config,
                                                  const std::string& path);

// Refuses (FormatError, exit 2) a table that no frame of `trial` falls within
// (io::check_time_overlap), naming both time spans; the warning when some frames do not.
std::vector<std::string> time_overlap_warnings(const io::MarkerTrial& trial,
                                               const std::string& trial_path,
                                               const io::OrientationTable& table,
                                               const std::string& table_path);

// The reader's warnings on stderr, one line each.
void print_warnings(const std::string& command, const std::string& path,
                    const std::vector<std::string>& warnings);

}  // namespace fabrik::apps
