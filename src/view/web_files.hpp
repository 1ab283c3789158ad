// What `fabrik view` serves over HTTP: a fixed table of URL -> file, nothing else. The page's
// own files come from the web root's flat listing (no subdirectories, names
// [A-Za-z0-9_-]+.js|.css, the file itself inside the root after resolving links); three.js
// from Debian's libjs-three. Nothing in a target is decoded, so an encoded `..` or `/` is just
// a name that is not in the table.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace fabrik::view {

struct WebFile {
  std::filesystem::path path;  // resolved: no links left
  const char* content_type = "";
  const char* cache_control = "";
};

class WebFiles {
 public:
  // `web_root`: the page's files (index.html, *.js, *.css); `three_root`: Debian's
  // /usr/share/javascript/three (build/three.module.js, examples/jsm/controls/OrbitControls.js).
  WebFiles(std::filesystem::path web_root, std::filesystem::path three_root);

  // The file a request target (origin form, "/app/x.js?v=1") maps to, or nothing (404).
  std::optional<WebFile> resolve(std::string_view target) const;

  const std::filesystem::path& web_root() const { return web_root_; }

 private:
  std::filesystem::path web_root_, three_root_;
};

// True for [A-Za-z0-9_-]+ followed by ".js" or ".css".
bool is_page_asset_name(std::string_view name);

}  // namespace fabrik::view
