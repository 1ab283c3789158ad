// The daemon config loader on any text: it returns a config or throws
// ConfigError naming the file; any other exception escapes and aborts (it
// would reach fabrikd's main without the file, pointer and fix).
// The config claims to live in a folder that does not exist, so a relative
// model path never reaches the disk; inputs that name an existing file as
// their model are skipped (this target fuzzes the loader, not the file system).
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <system_error>

#include "config/config_error.hpp"
#include "config/daemon_config.hpp"
#include "fuzz_check.hpp"

namespace {

constexpr const char* kFile = "/nonexistent-fabrik-fuzz/config.json";

bool names_a_file_on_disk(const std::string& text) {
  const nlohmann::json doc = nlohmann::json::parse(text, nullptr, false);
  if (!doc.is_object() || !doc.contains("model") || !doc["model"].is_string()) return false;
  std::filesystem::path path(doc["model"].get<std::string>());
  if (path.is_relative()) path = std::filesystem::path(kFile).parent_path() / path;
  std::error_code ec;
  const bool exists = std::filesystem::exists(path, ec);
  return exists || (ec && ec != std::errc::no_such_file_or_directory);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  if (names_a_file_on_disk(text)) return 0;
  try {
    const fabrik::DaemonConfig config = fabrik::load_daemon_config(text, kFile);
    fabrik::fuzz::require(!config.tracker.markers.empty(), "a config without tracked markers");
  } catch (const fabrik::ConfigError& e) {
    fabrik::fuzz::require_names_file(e.what(), kFile);
  }
  return 0;
}
