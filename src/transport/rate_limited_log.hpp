// Logging on the hot path: at most one message per period and kind, with a
// count of what was held back, so a flood of bad frames cannot flood the log
// (or slow the daemon down writing it).
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
  void warn(spdlog::format_string_t<Args...> fmt, Args&&... args) {
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < period_) {
      ++suppressed_;
      return;
    }
    if (suppressed_ > 0) spdlog::warn("({} similar messages suppressed)", suppressed_);
    suppressed_ = 0;
    last_ = now;
    spdlog::warn(fmt, std::forward<Args>(args)...);
  }

 private:
  std::chrono::steady_clock::duration period_;
  std::chrono::steady_clock::time_point last_{};
  long suppressed_ = 0;
};

}  // namespace fabrik::wire
