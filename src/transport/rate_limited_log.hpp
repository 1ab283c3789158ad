// Logging on the hot path: at most one message per period and kind, with a
// count of what was held back, so a flood of bad frames cannot flood the log
// (or slow the daemon down writing it). Callers pass only safe text
// (safe_text.hpp) where it quotes input. It never throws: a message that
// cannot be written (out of memory) is lost, the caller carries on.
#pragma once

#include <spdlog/spdlog.h>

#include <chrono>
#include <string_view>

namespace fabrik::wire {

class RateLimitedLog {
 public:
  explicit RateLimitedLog(std::chrono::steady_clock::duration period = std::chrono::seconds(1))
      : period_(period) {}

  template <class... Args>
  void warn(spdlog::format_string_t<Args...> fmt, Args&&... args) noexcept {
    log(spdlog::level::warn, fmt, std::forward<Args>(args)...);
  }
  template <class... Args>
  void info(spdlog::format_string_t<Args...> fmt, Args&&... args) noexcept {
    log(spdlog::level::info, fmt, std::forward<Args>(args)...);
  }

 private:
  template <class... Args>
  void log(spdlog::level::level_enum level, spdlog::format_string_t<Args...> fmt,
           Args&&... args) noexcept {
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < period_) {
      ++suppressed_;
      return;
    }
    last_ = now;
    try {
      if (suppressed_ > 0) spdlog::log(level, "({} similar messages suppressed)", suppressed_);
      suppressed_ = 0;
      spdlog::log(level, fmt, std::forward<Args>(args)...);
    } catch (...) {  // spdlog's own error report can fail too when memory is short
    }
  }

  std::chrono::steady_clock::duration period_;
  std::chrono::steady_clock::time_point last_{};
  long suppressed_ = 0;
};

}  // namespace fabrik::wire
