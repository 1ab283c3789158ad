// How the `fabrik` commands that take a recording read it: every reader warning printed on
// stderr ("fabrik solve: warning: walk.trc: ..."), and a file without 3D marker data refused
// (FormatError, exit 2) with what it holds instead.
#pragma once

#include <string>
#include <vector>

#include "io/marker_trial.hpp"

namespace fabrik::apps {

io::MarkerTrial read_trial_or_explain(const std::string& command, const std::string& path,
                                      bool keep_zeros);

// The reader's warnings on stderr, one line each.
void print_warnings(const std::string& command, const std::string& path,
                    const std::vector<std::string>& warnings);

}  // namespace fabrik::apps
