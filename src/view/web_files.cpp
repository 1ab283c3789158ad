#include "web_files.hpp"

#include <algorithm>
#include <system_error>

namespace fabrik::view {

namespace fs = std::filesystem;

namespace {

constexpr const char* kNoStore = "no-store";
constexpr const char* kPackage = "public, max-age=3600";  // Debian's three.js changes with the package

bool ends_with(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

// `root / relative` when it is a regular file whose resolved path lies inside the resolved
// root (a link out of the root, or a link to a directory, is not served); `flat`: directly
// in the root, not in a directory below it.
std::optional<fs::path> file_inside(const fs::path& root, const fs::path& relative, bool flat) {
  std::error_code ec;
  const fs::path real_root = fs::canonical(root, ec);
  if (ec) return std::nullopt;
  const fs::path real = fs::canonical(root / relative, ec);
  if (ec || !fs::is_regular_file(real, ec) || ec) return std::nullopt;
  const auto [r, _] = std::mismatch(real_root.begin(), real_root.end(), real.begin(), real.end());
  if (r != real_root.end()) return std::nullopt;
  if (flat && real.parent_path() != real_root) return std::nullopt;
  return real;
}

}  // namespace

bool is_page_asset_name(std::string_view name) {
  std::size_t stem = 0;
  if (ends_with(name, ".js"))
    stem = name.size() - 3;
  else if (ends_with(name, ".css"))
    stem = name.size() - 4;
  else
    return false;
  if (stem == 0) return false;
  for (std::size_t i = 0; i < stem; ++i) {
    const char c = name[i];
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                    c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

WebFiles::WebFiles(fs::path web_root, fs::path three_root)
    : web_root_(std::move(web_root)), three_root_(std::move(three_root)) {}

std::optional<WebFile> WebFiles::resolve(std::string_view target) const {
  // The query string is ignored (cache busting); a fragment never reaches a server.
  if (const auto q = target.find('?'); q != std::string_view::npos) target = target.substr(0, q);
  if (target == "/" || target == "/index.html") {
    const auto p = file_inside(web_root_, "index.html", true);
    if (!p) return std::nullopt;
    return WebFile{*p, "text/html; charset=utf-8", kNoStore};
  }
  if (target == "/three/build/three.module.js" ||
      target == "/three/examples/jsm/controls/OrbitControls.js") {
    const auto p = file_inside(three_root_, fs::path(std::string(target.substr(7))), false);
    if (!p) return std::nullopt;
    return WebFile{*p, "text/javascript; charset=utf-8", kPackage};
  }
  constexpr std::string_view kApp = "/app/";
  if (target.substr(0, kApp.size()) != kApp) return std::nullopt;
  const std::string_view name = target.substr(kApp.size());
  if (!is_page_asset_name(name)) return std::nullopt;
  const auto p = file_inside(web_root_, fs::path(std::string(name)), true);
  if (!p) return std::nullopt;
  return WebFile{*p, ends_with(name, ".js") ? "text/javascript; charset=utf-8" : "text/css; charset=utf-8",
                 kNoStore};
}

}  // namespace fabrik::view
