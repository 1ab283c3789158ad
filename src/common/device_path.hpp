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

}  // namespace fabrik
