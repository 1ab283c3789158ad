// OpenSim's tables (.sto storage files and .mot motion files, versions 1 and 3): header lines up
// to `endheader` (a name line, `key=value` lines, free text), then a tab-separated table whose
// first column is time. Read to say what a file holds (`fabrik info`), not to track: such a file
// holds coordinates, orientations or forces, not markers.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace fabrik::io {

struct OpenSimTable {
  std::string name;                                     // the header's first line, if not key=value
  std::vector<std::pair<std::string, std::string>> header;  // key=value lines, in order
  std::vector<std::string> columns;                     // the labels, time first
  std::size_t rows = 0;
  double first_time_s = 0.0, last_time_s = 0.0;
  double rate_hz = 0.0;      // DataRate, else from the time column (rows - 1 over the span)
  std::string rate_source;   // "from DataRate", "from the time column", "" when unknown
  std::string cell_kind;     // "numbers", or "quaternions (w,x,y,z)" / "3-vectors" when cells
                             // hold comma-separated tuples
  // Rows with a different number of fields, nRows/nColumns that disagree with the table, ...
  std::vector<std::string> warnings;
};

// Throws FormatError (path first) when there is no `endheader` or no table after it.
OpenSimTable read_opensim_table(const std::string& path);

}  // namespace fabrik::io
