#include "config_error.hpp"

#include "common/safe_text.hpp"

namespace fabrik {

ConfigError::ConfigError(const std::string& file, const std::string& pointer,
                         const std::string& problem, const std::string& fix)
    : std::runtime_error(safe_lines(file + ": at " + (pointer.empty() ? std::string("/") : pointer) +
                                    ": " + problem + (fix.empty() ? "" : ". Fix: " + fix))),
      file_(file),
      pointer_(pointer.empty() ? "/" : pointer) {}

}  // namespace fabrik
