#include "resources.hpp"

#include <filesystem>

#include "config_error.hpp"
#include "json_reader.hpp"

namespace fabrik {

namespace embedded {
std::string_view paper_experiment();
std::string_view paper_upper_body();
std::string_view paper_upper_body_limits();
std::string_view fullbody();
std::string_view default_config();
}  // namespace embedded

std::optional<std::string_view> embedded_config(std::string_view relative_path) {
  if (relative_path == "paper_experiment.json") return embedded::paper_experiment();
  if (relative_path == "models/paper_upper_body.json") return embedded::paper_upper_body();
  if (relative_path == "models/paper_upper_body_limits.json")
    return embedded::paper_upper_body_limits();
  if (relative_path == "default.json") return embedded::default_config();
  if (relative_path == "models/fullbody.json") return embedded::fullbody();
  return std::nullopt;
}

std::string read_config_text(const std::string& path) {
  // Anything at the path (a file, a directory, a dangling link) is read or
  // refused as it is; only where nothing is does an embedded file stand in.
  std::error_code ec;
  const bool on_disk = std::filesystem::symlink_status(path, ec).type() !=
                       std::filesystem::file_type::not_found;
  if (on_disk || !embedded_config(path)) {
    std::string text;
    if (auto p = read_text_file(path, text)) {
      if (!on_disk)
        throw ConfigError(path, "", "no such file (and no embedded default of that name)",
                          "check the path");
      throw ConfigError(path, "", p->problem, p->fix);
    }
    return text;
  }
  return std::string(*embedded_config(path));
}

}  // namespace fabrik
