// Whether a path names a stream: a device (/dev/null, a terminal), a pipe or a socket. An output
// there is discarded, shown or read as it comes, never replaced, so it has no format to name
// (two outputs may share /dev/null or /dev/ptmx only: tools/distinct_files.hpp).
#pragma once

#include <sys/stat.h>

#include <string>

namespace fabrik {

// "device", "pipe" or "socket" (for messages), or "" for a regular file, a folder or nothing.
inline const char* stream_kind(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || S_ISREG(st.st_mode) || S_ISDIR(st.st_mode)) return "";
  if (S_ISFIFO(st.st_mode)) return "pipe";
  if (S_ISSOCK(st.st_mode)) return "socket";
  return "device";
}

inline bool is_stream(const std::string& path) {
  return *stream_kind(path) != '\0';
}

// Whether `path` is where this process's standard output goes (/dev/stdout, /dev/fd/1, or the
// terminal, pipe or file those name), /dev/null aside: a command's text summary then goes to
// stderr, so a pipe gets the output alone and a redirected file is not overwritten by it.
inline bool is_standard_output(const std::string& path) {
  struct stat at_path {};
  struct stat out {};
  struct stat null {};
  if (path.empty() || ::stat(path.c_str(), &at_path) != 0 || ::fstat(1, &out) != 0) return false;
  if (S_ISCHR(out.st_mode) && ::stat("/dev/null", &null) == 0 && out.st_rdev == null.st_rdev)
    return false;
  return at_path.st_dev == out.st_dev && at_path.st_ino == out.st_ino;
}

}  // namespace fabrik
