// One subject's markers out of a recording of several (`fabrik solve
// --subject`): a Vicon C3D of two subjects labels its markers
// `Subject:Marker`, as Vicon, QTM and Motive stream them
// (docs/multi-subject.md).
#pragma once

#include <string>
#include <vector>

#include "io/marker_trial.hpp"

namespace fabrik {

// The subjects a trial's labels name (the part before the first ':'), in the order first seen.
std::vector<std::string> trial_subjects(const io::MarkerTrial& trial);
// The trial with only `subject`'s markers, their labels without "subject:".
// Throws std::runtime_error, naming the subjects the trial has, when it has none of them.
io::MarkerTrial subject_trial(const io::MarkerTrial& trial, const std::string& subject);

}  // namespace fabrik
