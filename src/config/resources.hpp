// Files from config/ compiled into the binaries, so the executables run on
// their defaults from any directory.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace fabrik {

// The embedded copy of config/<relative_path>, if it is one of the embedded files.
std::optional<std::string_view> embedded_config(std::string_view relative_path);

// The text of `path`: the file on disk if anything is at that path (read
// with read_text_file's checks: a regular file of at most 16 MiB), else the
// embedded config file of that relative path. Throws ConfigError otherwise.
std::string read_config_text(const std::string& path);

}  // namespace fabrik
