// A small typed reader over nlohmann::json that remembers where it is, so
// every error can name the file and JSON pointer (RFC 6901) of the problem.
#pragma once

#include <Eigen/Core>
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "config_error.hpp"

namespace fabrik {

class JsonReader {
 public:
  JsonReader(const nlohmann::json& value, std::string file, std::string pointer = "")
      : value_(value), file_(std::move(file)), pointer_(std::move(pointer)) {}

  // Parses text; a syntax error names the line and column and the JSON
  // pointer of the value being read, and so does a number that does not fit
  // a double (1e400) or nesting deeper than kMaxJsonDepth.
  static nlohmann::json parse(std::string_view text, const std::string& file);
  // Reads (read_text_file) and parses a file; any problem is a ConfigError.
  static nlohmann::json parse_file(const std::string& path);

  const nlohmann::json& value() const { return value_; }
  const std::string& file() const { return file_; }
  const std::string& pointer() const { return pointer_; }

  [[noreturn]] void fail(const std::string& problem, const std::string& fix) const;
  JsonReader at(const std::string& key) const;  // requires an object member
  JsonReader at(std::size_t index) const;       // requires an array element
  bool has(const std::string& key) const;

  const JsonReader& expect_object() const;
  const JsonReader& expect_array() const;
  // Rejects keys outside `allowed`, suggesting the nearest allowed key.
  const JsonReader& only_keys(std::initializer_list<std::string_view> allowed) const;

  std::string as_string() const;
  double as_number() const;                        // finite
  double as_number(double min, double max) const;  // finite, in [min, max]
  long long as_integer(long long min, long long max) const;
  bool as_bool() const;
  Eigen::Vector3d as_vec3() const;  // [x, y, z], finite

  // The same with a default when the key is absent.
  std::string get(const std::string& key, const std::string& fallback) const;
  double get(const std::string& key, double fallback, double min, double max) const;
  long long get(const std::string& key, long long fallback, long long min, long long max) const;
  bool get(const std::string& key, bool fallback) const;

 private:
  const nlohmann::json& value_;
  std::string file_;
  std::string pointer_;
};

// One of a few named values; the error lists them.
template <class T>
T read_choice(const JsonReader& value, const std::string& what,
              std::initializer_list<std::pair<const char*, T>> choices) {
  const std::string v = value.as_string();
  std::string names;
  for (const auto& [name, choice] : choices) {
    if (v == name) return choice;
    names += (names.empty() ? "\"" : " or \"") + std::string(name) + "\"";
  }
  value.fail("unknown " + what + " '" + v + "'", "use " + names);
}

// Config, model and template files: larger ones are refused (said in the error).
constexpr std::size_t kMaxConfigFileBytes = std::size_t{16} << 20;
constexpr int kMaxJsonDepth = 256;
// Values (numbers, strings, arrays, objects...) in one file: the largest
// real model or calibrated config holds a few tens of thousands; this bounds
// what the parsed document takes in memory (docs/daemon.md, "Config").
constexpr std::size_t kMaxJsonValues = std::size_t{1} << 20;

// Why a file cannot be read, and what to do about it.
struct FileProblem {
  std::string problem, fix;
};

// Reads `path` into `text` if it is a regular file (symbolic links followed)
// of at most max_bytes; anything else (a directory, a device such as
// /dev/zero, a FIFO, a symlink loop, a missing or unreadable file) is a
// problem, found without blocking and without reading more than max_bytes + 1.
std::optional<FileProblem> read_text_file(const std::string& path, std::string& text,
                                          std::size_t max_bytes = kMaxConfigFileBytes);

// "pointer/escaped~1key": RFC 6901 escaping of one reference token.
std::string json_pointer_token(const std::string& key);

}  // namespace fabrik
