// Refuses a command whose output would overwrite one of its inputs or another of its outputs:
// `fabrik solve --input walk.trc --output walk.trc` replaced the trial it read, and
// `--output j.trc --angles j.trc` lost the joint centres to the angles.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace fabrik::tools {

struct NamedFile {
  std::string option;  // "--output", or "--markers (its .filled.csv)"
  std::string path;    // empty: not given, skipped
  bool output = true;  // inputs may share a file (a static trial as the trial); outputs may not
};

// Throws std::invalid_argument naming both options when an output's path is the same file as
// another given path (the same after symlinks, `.` and `..`; or a hard link of it).
void require_distinct_files(const std::vector<NamedFile>& files);

}  // namespace fabrik::tools
