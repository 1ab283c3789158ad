/// @file
/// Setup-time errors in JSON inputs: every message names the file, the JSON
/// pointer of the offending value, what is wrong and how to fix it. what() is
/// safe text (escaped): a file name, a value or a parser message
/// that quotes raw input cannot put bytes that are not UTF-8 or control
/// characters on a terminal or in a log; file() and pointer() stay as given.
#pragma once

#include <stdexcept>
#include <string>

namespace fabrik {

/// A setup-time error in a JSON input (see the file's description).
class ConfigError : public std::runtime_error {
 public:
  /// what() is "FILE: at POINTER: PROBLEM. Fix: FIX" (no fix part when `fix` is empty);
  /// an empty pointer means the whole document, "/".
  ConfigError(const std::string& file, const std::string& pointer, const std::string& problem,
              const std::string& fix);
  const std::string& file() const { return file_; }  ///< the file, as given
  /// The JSON pointer of the offending value (RFC 6901), "/" for the whole document.
  const std::string& pointer() const { return pointer_; }

 private:
  std::string file_;
  std::string pointer_;
};

}  // namespace fabrik
