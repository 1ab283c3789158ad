// Opening and finishing an output file, for every writer of the project: a write that failed
// (a full disk, a removed file) is an error, not a truncated file and exit 0.
#pragma once

#include <fstream>
#include <string>

#include "io/marker_trial.hpp"

namespace fabrik::io {

// A file that could not be written. what() is "PATH: PROBLEM (the system's reason)", the
// reason left out when the system gave none; error_number() is that errno (0: none), kept for
// callers that report it in their own terms (Python's OSError and its subclasses).
class OutputFileError : public FormatError {
 public:
  OutputFileError(const std::string& path, const std::string& problem, int error_number);
  int error_number() const { return error_number_; }
  std::string problem() const;  // what() without the path

 private:
  int error_number_;
};

// Opens `path` for binary writing (truncating); OutputFileError if that fails.
std::ofstream open_output_file(const std::string& path);

// Closes `out` and throws OutputFileError if any write to it, or the close, failed. A buffered
// stream writes its last bytes at the close: a check before it misses a full disk.
void finish_output_file(std::ofstream& out, const std::string& path);

}  // namespace fabrik::io
