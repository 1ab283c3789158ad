// Whether a path names a device such as /dev/null: an output there is discarded or shown, never
// replaced, so it has no format to name (two outputs may share /dev/null only:
// tools/distinct_files.hpp).
#pragma once

#include <filesystem>
#include <string>
#include <system_error>

namespace fabrik {

inline bool is_device(const std::string& path) {
  std::error_code ec;
  return std::filesystem::is_character_file(path, ec);
}

}  // namespace fabrik
