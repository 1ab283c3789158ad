#include "io/recording_info.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "common/ascii_case.hpp"

namespace fabrik::io {

const char* const kInfoFormats = ".trc, .c3d (markers), .sto, .mot (OpenSim tables)";

RecordingInfo inspect_recording(const std::string& path) {
  const std::string ext = ascii_lower(std::filesystem::path(path).extension().string());
  RecordingInfo info;
  info.path = path;
  if (ext == ".sto" || ext == ".mot") {
    info.kind = "table";
    // Described as they are used (a bad cell is missing, its row kept: orientation tables).
    info.table = read_opensim_table(path, {.bad_cells_missing = true, .refuse_time_back = false});
    return info;
  }
  if (ext != ".trc" && ext != ".c3d") {
    throw FormatError(path, "unknown file type '" + ext + "': fabrik info reads " +
                                std::string(kInfoFormats));
  }
  info.kind = "markers";
  // Describe what solve would refuse (repeated labels, time going back): they are findings here.
  info.trial = read_trial(path, {.allow_truncated_data = true, .refuse_ambiguous = false});
  const MarkerTrial& t = info.trial;
  for (std::size_t m = 0; m < t.markers(); ++m) {
    MarkerSamples s{.label = t.labels[m]};
    s.zeros = m < t.source.zero_samples.size() ? t.source.zero_samples[m] : 0;
    std::size_t run = 0;
    for (std::size_t f = 0; f < t.frames(); ++f) {
      run = t.at(f, m).allFinite() ? 0 : run + 1;
      s.missing += run > 0 ? 1 : 0;
      s.longest_gap = std::max(s.longest_gap, run);
    }
    info.markers.push_back(std::move(s));
  }
  return info;
}

}  // namespace fabrik::io
