#include "subject_markers.hpp"

#include <algorithm>
#include <stdexcept>

namespace fabrik {

std::vector<std::string> trial_subjects(const io::MarkerTrial& trial) {
  std::vector<std::string> subjects;
  for (const std::string& label : trial.labels) {
    const std::size_t colon = label.find(':');
    if (colon == std::string::npos || colon == 0) continue;
    const std::string subject = label.substr(0, colon);
    if (std::find(subjects.begin(), subjects.end(), subject) == subjects.end())
      subjects.push_back(subject);
  }
  return subjects;
}

namespace {

// The option's name alone: "--subject", or "subject" of a keyword "subject=".
std::string option_name(const std::string& option) {
  return option.ends_with('=') ? option.substr(0, option.size() - 1) : option;
}

}  // namespace

DaemonConfig subject_config(DaemonConfig config, const std::string& subject,
                            const std::string& option) {
  const std::string name = option_name(option);
  if (!config.subjects.empty()) {
    auto it = std::find_if(config.subjects.begin(), config.subjects.end(),
                           [&](const SubjectConfig& s) { return s.name == subject; });
    if (it == config.subjects.end())
      throw std::runtime_error(config.file + " lists subjects: give " + name +
                               " with one of them (or the subject's own config)");
    config.tracker = it->tracker;
    config.sensors = it->sensors;
  } else if (!subject.empty()) {
    const std::string shared = unprefix_subject_targets(config.tracker, subject);
    if (!shared.empty())
      throw std::runtime_error(config.file + " has targets '" + subject + ":" + shared + "' and '" +
                               shared + "': with " + given_option(option, subject) +
                               " both would be '" + shared + "'; keep one of them");
  }
  return config;
}

std::string given_option(const std::string& option, const std::string& value) {
  return option.ends_with('=') ? option + "'" + value + "'" : option + " " + value;
}

io::MarkerTrial subject_trial(const io::MarkerTrial& trial, const std::string& subject,
                              const std::string& option) {
  const std::string prefix = subject + ":";
  std::vector<std::size_t> kept;
  for (std::size_t i = 0; i < trial.labels.size(); ++i)
    if (trial.labels[i].starts_with(prefix) && trial.labels[i].size() > prefix.size())
      kept.push_back(i);
  if (kept.empty()) {
    const std::vector<std::string> subjects = trial_subjects(trial);
    std::string named;
    for (const std::string& s : subjects) named += (named.empty() ? "" : ", ") + s;
    throw std::runtime_error(given_option(option, subject) +
                             ": no marker of the trial is labelled " + prefix + "MARKER. Fix: " +
                             (subjects.empty() ? std::string("the trial names no subjects (one "
                                                             "person per file): leave out ") +
                                                     option_name(option)
                                               : "choose one of the trial's subjects: " + named));
  }
  io::MarkerTrial out = trial;
  out.labels.clear();
  for (std::size_t i : kept) out.labels.push_back(trial.labels[i].substr(prefix.size()));
  const std::size_t frames = trial.frames();
  out.positions_m.resize(frames * kept.size());
  for (std::size_t f = 0; f < frames; ++f)
    for (std::size_t k = 0; k < kept.size(); ++k)
      out.positions_m[f * kept.size() + k] = trial.at(f, kept[k]);
  // Per-marker facts follow the markers they describe.
  if (trial.source.zero_samples.size() == trial.labels.size()) {
    out.source.zero_samples.clear();
    for (std::size_t i : kept) out.source.zero_samples.push_back(trial.source.zero_samples[i]);
  }
  return out;
}

}  // namespace fabrik
