// Case folding for what is typed in any case: host names (RFC 4343), file extensions,
// marker names, protocol words. Byte by byte, as std::tolower does.
#pragma once

#include <cctype>
#include <string>
#include <string_view>

namespace fabrik {

inline char ascii_lower(char c) {
  return static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
}

inline std::string ascii_lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = ascii_lower(c);
  return out;
}

inline bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (ascii_lower(a[i]) != ascii_lower(b[i])) return false;
  return true;
}

// A file name's extension in any case: "WALK.TRC" has ".trc".
inline bool has_suffix_ci(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && iequals(s.substr(s.size() - suffix.size()), suffix);
}

}  // namespace fabrik
