// Opening and finishing an output file, for every writer of the project: a write that failed
// (a full disk, a removed file) is an error, not a truncated file and exit 0.
#pragma once

#include <fstream>
#include <string>

namespace fabrik::io {

// Opens `path` for binary writing (truncating); FormatError if that fails.
std::ofstream open_output_file(const std::string& path);

// Closes `out` and throws FormatError if any write to it, or the close, failed. A buffered
// stream writes its last bytes at the close: a check before it misses a full disk.
void finish_output_file(std::ofstream& out, const std::string& path);

}  // namespace fabrik::io
