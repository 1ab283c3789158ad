#include "io/output_file.hpp"

#include <cerrno>
#include <cstring>

namespace fabrik::io {

namespace {

std::string with_reason(const std::string& problem, int error_number) {
  return error_number == 0 ? problem : problem + " (" + std::strerror(error_number) + ")";
}

// A write that failed before the close left its errno; other calls may have set errno since, so
// only a reason a write gives is taken from it.
int write_errno(int error_number) {
  switch (error_number) {
    case ENOSPC:
    case EDQUOT:
    case EFBIG:
    case EIO:
    case EPIPE:
    case ESTALE:
      return error_number;
    default:
      return 0;
  }
}

}  // namespace

OutputFileError::OutputFileError(const std::string& path, const std::string& problem,
                                 int error_number)
    : FormatError(path, with_reason(problem, error_number)), error_number_(error_number) {}

std::string OutputFileError::problem() const {
  return std::string(what()).substr(path().size() + 2);  // what() is "PATH: PROBLEM"
}

// errno is cleared first: a stream sets no errno of its own, so one left from earlier would
// name a reason that is not this failure's.
std::ofstream open_output_file(const std::string& path) {
  errno = 0;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw OutputFileError(path, "cannot open the file for writing", errno);
  return out;
}

void finish_output_file(std::ofstream& out, const std::string& path) {
  const int before_close = out ? 0 : write_errno(errno);
  errno = 0;
  out.close();
  if (out) return;
  const int error_number = before_close != 0 ? before_close : errno;
  // The system's reason, where it gave one, says what the guess would.
  throw OutputFileError(
      path, error_number != 0 ? "writing failed" : "writing failed (disk full or file removed?)",
      error_number);
}

}  // namespace fabrik::io
