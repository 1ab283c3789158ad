/// @file
/// Setup-time errors in JSON inputs: every message names the file, the JSON
/// pointer of the offending value, what is wrong and how to fix it. what() is
/// safe text (common/safe_text.hpp): a file name, a value or a parser message
/// that quotes raw input cannot put bytes that are not UTF-8 or control
/// characters on a terminal or in a log; file() and pointer() stay as given.
#pragma once

#include <stdexcept>
#include <string>

namespace fabrik {

class ConfigError : public std::runtime_error {
 public:
  ConfigError(const std::string& file, const std::string& pointer, const std::string& problem,
              const std::string& fix);
  const std::string& file() const { return file_; }
  const std::string& pointer() const { return pointer_; }

 private:
  std::string file_;
  std::string pointer_;
};

}  // namespace fabrik
