#include "json_reader.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

namespace fabrik {

namespace {
std::string type_name(const nlohmann::json& j) {
  if (j.is_number()) return "a number";
  if (j.is_string()) return "a string";
  if (j.is_boolean()) return "a boolean";
  if (j.is_array()) return "an array";
  if (j.is_object()) return "an object";
  return "null";
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}
}  // namespace

std::string json_pointer_token(const std::string& key) {
  std::string out;
  for (char c : key) {
    if (c == '~')
      out += "~0";
    else if (c == '/')
      out += "~1";
    else
      out += c;
  }
  return out;
}

nlohmann::json JsonReader::parse(std::string_view text, const std::string& file) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    // Turn the byte offset into line:column, which editors understand.
    std::size_t line = 1, col = 1;
    for (std::size_t i = 0; i + 1 < e.byte && i < text.size(); ++i) {
      if (text[i] == '\n') {
        ++line;
        col = 1;
      } else {
        ++col;
      }
    }
    std::string what = e.what();
    if (auto pos = what.find("syntax error"); pos != std::string::npos) what = what.substr(pos);
    throw ConfigError(file, "",
                      "not valid JSON (line " + std::to_string(line) + ", column " +
                          std::to_string(col) + "): " + what,
                      "correct the JSON syntax at that position");
  }
}

nlohmann::json JsonReader::parse_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path, "", "cannot open the file", "check the path and permissions");
  std::ostringstream text;
  text << in.rdbuf();
  return parse(text.str(), path);
}

void JsonReader::fail(const std::string& problem, const std::string& fix) const {
  throw ConfigError(file_, pointer_, problem, fix);
}

bool JsonReader::has(const std::string& key) const {
  return value_.is_object() && value_.contains(key);
}

JsonReader JsonReader::at(const std::string& key) const {
  expect_object();
  auto it = value_.find(key);
  if (it == value_.end())
    JsonReader(value_, file_, pointer_ + "/" + json_pointer_token(key))
        .fail("required field '" + key + "' is missing", "add \"" + key + "\"");
  return JsonReader(*it, file_, pointer_ + "/" + json_pointer_token(key));
}

JsonReader JsonReader::at(std::size_t index) const {
  expect_array();
  return JsonReader(value_.at(index), file_, pointer_ + "/" + std::to_string(index));
}

const JsonReader& JsonReader::expect_object() const {
  if (!value_.is_object()) fail("expected an object, found " + type_name(value_), "use { ... }");
  return *this;
}

const JsonReader& JsonReader::expect_array() const {
  if (!value_.is_array()) fail("expected an array, found " + type_name(value_), "use [ ... ]");
  return *this;
}

const JsonReader& JsonReader::only_keys(std::initializer_list<std::string_view> allowed) const {
  expect_object();
  for (auto it = value_.begin(); it != value_.end(); ++it) {
    const std::string& key = it.key();
    if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
    std::string_view best;
    std::size_t best_d = 3;  // suggest only close matches
    std::string list;
    for (std::string_view a : allowed) {
      list += (list.empty() ? "" : ", ") + std::string(a);
      if (const std::size_t d = edit_distance(key, a); d < best_d) {
        best_d = d;
        best = a;
      }
    }
    JsonReader(*it, file_, pointer_ + "/" + json_pointer_token(key))
        .fail("unknown field '" + key + "'", best.empty()
                                                 ? "remove it (allowed here: " + list + ")"
                                                 : "did you mean '" + std::string(best) + "'?");
  }
  return *this;
}

std::string JsonReader::as_string() const {
  if (!value_.is_string()) fail("expected a string, found " + type_name(value_), "use \"...\"");
  return value_.get<std::string>();
}

double JsonReader::as_number() const {
  if (!value_.is_number()) fail("expected a number, found " + type_name(value_), "use a number");
  const double v = value_.get<double>();
  if (!std::isfinite(v)) fail("the number is not finite", "use a finite number");
  return v;
}

double JsonReader::as_number(double min, double max) const {
  const double v = as_number();
  if (v < min || v > max) {
    std::ostringstream range;
    range << "use a value in [" << min << ", " << max << "]";
    std::ostringstream got;
    got << "value " << v << " is out of range";
    fail(got.str(), range.str());
  }
  return v;
}

long long JsonReader::as_integer(long long min, long long max) const {
  if (!value_.is_number_integer())
    fail("expected an integer, found " + type_name(value_), "use a whole number");
  const long long v = value_.get<long long>();
  if (v < min || v > max)
    fail("value " + std::to_string(v) + " is out of range",
         "use a value in [" + std::to_string(min) + ", " + std::to_string(max) + "]");
  return v;
}

bool JsonReader::as_bool() const {
  if (!value_.is_boolean())
    fail("expected true or false, found " + type_name(value_), "use true or false");
  return value_.get<bool>();
}

Eigen::Vector3d JsonReader::as_vec3() const {
  if (!value_.is_array() || value_.size() != 3)
    fail("expected [x, y, z], found " + type_name(value_) +
             (value_.is_array() ? " of " + std::to_string(value_.size()) + " elements" : ""),
         "give three numbers");
  return {at(std::size_t{0}).as_number(), at(std::size_t{1}).as_number(),
          at(std::size_t{2}).as_number()};
}

std::string JsonReader::get(const std::string& key, const std::string& fallback) const {
  return has(key) ? at(key).as_string() : fallback;
}
double JsonReader::get(const std::string& key, double fallback, double min, double max) const {
  return has(key) ? at(key).as_number(min, max) : fallback;
}
long long JsonReader::get(const std::string& key, long long fallback, long long min,
                          long long max) const {
  return has(key) ? at(key).as_integer(min, max) : fallback;
}
bool JsonReader::get(const std::string& key, bool fallback) const {
  return has(key) ? at(key).as_bool() : fallback;
}

}  // namespace fabrik
