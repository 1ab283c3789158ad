// `fabrik bench subjects`: several subjects tracked by one daemon
// (docs/multi-subject.md). For each count of synthetic subjects (spaced 2 m
// apart in the lab, each its own phase of the motion), a daemon with that
// many subjects runs its loop on a thread of its own over loopback tcp; a
// source sends one frame with every subject's markers (Subject:Marker) at a
// fixed rate and a subscriber times, per frame, from the source's send to
// the arrival of the last subject's pose. Counts run in turn within one run
// so that their ratios share the machine's load.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fabrik::bench {

struct SubjectsOptions {
  std::vector<int> counts = {1, 2, 4, 8};
  double rate_hz = 240.0;
  double seconds = 10.0;  // per count
  // A subject's config (as `fabrik calibrate` writes it); empty: the built-in default.
  std::string config;
};
nlohmann::json run_subjects(const SubjectsOptions& options);
std::string subjects_table(const nlohmann::json& result);

}  // namespace fabrik::bench
