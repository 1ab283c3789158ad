// What a recording holds, for `fabrik info`: a marker file's format, rate, units, frames,
// markers with their missing samples and exact zeros, analog channels and rotations; or an
// OpenSim table's columns, rows and time span. Users check a file with it before they write a
// template.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "io/marker_trial.hpp"
#include "io/opensim_table.hpp"

namespace fabrik::io {

struct MarkerSamples {
  std::string label;
  std::size_t missing = 0;      // samples without a position (exact zeros included)
  std::size_t zeros = 0;        // of them, exact (0, 0, 0) samples
  std::size_t longest_gap = 0;  // frames
};

struct RecordingInfo {
  std::string path;
  std::string kind;  // "markers" (TRC, C3D) or "table" (OpenSim .sto/.mot)
  // Marker files:
  // As `fabrik solve` reads it (zeros missing), truncated data allowed, and what solve refuses
  // (repeated labels, a Time column going back) read and recorded in trial.source.
  MarkerTrial trial;
  std::vector<MarkerSamples> markers;
  // OpenSim tables:
  std::optional<OpenSimTable> table;
};

// The formats it understands, for messages: ".trc, .c3d (markers), .sto, .mot (OpenSim tables)".
extern const char* const kInfoFormats;

// By extension (any case). Throws FormatError for a file it cannot read or a type it does not
// know (naming the types it knows).
RecordingInfo inspect_recording(const std::string& path);

}  // namespace fabrik::io
