#include "resources.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>

#include "config_error.hpp"

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
  if (std::filesystem::exists(path)) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw ConfigError(path, "", "cannot open the file", "check its permissions");
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  }
  if (auto text = embedded_config(path)) return std::string(*text);
  throw ConfigError(path, "", "no such file (and no embedded default of that name)",
                    "check the path");
}

}  // namespace fabrik
