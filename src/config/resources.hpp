// Files from config/ compiled into the binaries, so the executables run on
// their defaults from any directory.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace fabrik {

// The embedded copy of config/<relative_path>, if it is one of the embedded files.
std::optional<std::string_view> embedded_config(std::string_view relative_path);

// The text of `path`: a file on disk if it exists, else the embedded config
// file of that relative path. Throws ConfigError when neither exists.
std::string read_config_text(const std::string& path);

}  // namespace fabrik
