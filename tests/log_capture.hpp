// The daemon's log for the length of a test, to check what it says.
#pragma once

#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include <memory>
#include <string>

namespace fabrik::test {

// The daemon's log for the length of a test: a ring of formatted lines as
// the default logger (installed before the daemon starts, restored after it
// stopped: spdlog's free functions read the default logger without a lock).
class LogCapture {
 public:
  LogCapture() : sink_(std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(1000)) {
    sink_->set_pattern("%l %v");
    auto logger = std::make_shared<spdlog::logger>("captured", sink_);
    logger->set_level(spdlog::level::info);
    spdlog::set_default_logger(logger);
  }
  ~LogCapture() { spdlog::set_default_logger(previous_); }
  LogCapture(const LogCapture&) = delete;
  LogCapture& operator=(const LogCapture&) = delete;

  // The first line that starts with `prefix` and holds `phrase`, or "".
  std::string find(const std::string& prefix, const std::string& phrase) const {
    for (const std::string& line : sink_->last_formatted())
      if (line.rfind(prefix, 0) == 0 && line.find(phrase) != std::string::npos) return line;
    return "";
  }
  std::string all() const {
    std::string text;
    for (const std::string& line : sink_->last_formatted()) text += line;
    return text;
  }

 private:
  std::shared_ptr<spdlog::logger> previous_ = spdlog::default_logger();
  std::shared_ptr<spdlog::sinks::ringbuffer_sink_mt> sink_;
};

}  // namespace fabrik::test
