// What every fuzz target shares: a failed property aborts with a message, so
// libFuzzer records the input as a crash (exceptions other than the documented
// error type escape on their own and abort the same way).
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string_view>

namespace fabrik::fuzz {

[[noreturn]] inline void fail(std::string_view what) {
  std::fprintf(stderr, "FUZZ PROPERTY VIOLATED: %.*s\n", static_cast<int>(what.size()),
               what.data());
  std::abort();
}

inline void require(bool property, std::string_view what) {
  if (!property) fail(what);
}

// Errors name their file first (ConfigError and io::FormatError both promise it).
inline void require_names_file(std::string_view message, std::string_view file) {
  require(message.substr(0, file.size()) == file && message.size() > file.size() + 2,
          "the error message does not start with the file's name");
}

}  // namespace fabrik::fuzz
