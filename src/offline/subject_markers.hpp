// One subject's markers out of a recording of several (`fabrik solve
// --subject`): a Vicon C3D of two subjects labels its markers
// `Subject:Marker`, as Vicon, QTM and Motive stream them
// (docs/multi-subject.md).
#pragma once

#include <string>
#include <vector>

#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"

namespace fabrik {

// The subjects a trial's labels name (the part before the first ':'), in the order first seen.
std::vector<std::string> trial_subjects(const io::MarkerTrial& trial);
// The trial with only `subject`'s markers, their labels without "subject:".
// Throws std::runtime_error, naming the subjects the trial has, when it has none of them;
// `option` is the caller's name for the choice (see given_option).
io::MarkerTrial subject_trial(const io::MarkerTrial& trial, const std::string& subject,
                              const std::string& option = "--subject");
// The config that tracks `subject` (`fabrik solve --subject`): a multi-subject config's
// subject's tracking; a subject's own config with its targets' "subject:" prefix taken off
// (calibrated from this very file). An empty `subject` keeps the config, but a multi-subject
// config needs one. Throws std::runtime_error with the fix; `option` names the choice.
DaemonConfig subject_config(DaemonConfig config, const std::string& subject,
                            const std::string& option = "--subject");
// An option as a user types it: "--subject S" for a command line's, "subject='S'" for a
// keyword argument's (an `option` ending in '=').
std::string given_option(const std::string& option, const std::string& value);

}  // namespace fabrik
