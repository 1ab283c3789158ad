// `fabrik eval reduction`: joint centres with marker subsets left out,
// against the full-set solution.
#pragma once

#include <string>
#include <vector>

#include "subject.hpp"

namespace fabrik::eval {

struct DropSet {
  std::string name;
  std::vector<std::string> markers;  // tracked markers left out for the whole trial
};

// Marker subsets for gait2354 (subject01): one marker of each thigh and shank
// cluster, the arms down to the wrists, the thigh clusters, the head, and a
// minimal set.
std::vector<DropSet> gait2354_drop_sets();

struct GroupDeviation {
  std::string group;
  double rms_m = 0.0, max_m = 0.0;
};

struct ReductionRow {
  std::string name;
  int dropped = 0, kept = 0;
  double rms_m = 0.0, max_m = 0.0;  // over every reference point and frame
  std::string max_point;
  double marker_rms_mean_m = 0.0;  // residual of the kept markers
  std::vector<GroupDeviation> groups;
};

// Throws std::invalid_argument if a drop set names a marker that is not tracked.
std::vector<ReductionRow> eval_reduction(const DaemonConfig& config, const io::MarkerTrial& trial,
                                         const std::vector<DropSet>& sets);

}  // namespace fabrik::eval
