#include "json_reader.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
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

namespace {

// nlohmann's DOM builder, plus the JSON pointer of the value being read, so
// that a parse error (a syntax error, a number overflowing a double) names
// where it is, and a depth limit.
class PointerTrackingSax {
 public:
  using json = nlohmann::json;
  explicit PointerTrackingSax(json& root) : dom_(root) {}

  bool null() { return value() && dom_.null(); }
  bool boolean(bool v) { return value() && dom_.boolean(v); }
  bool number_integer(json::number_integer_t v) { return value() && dom_.number_integer(v); }
  bool number_unsigned(json::number_unsigned_t v) { return value() && dom_.number_unsigned(v); }
  bool number_float(json::number_float_t v, const json::string_t& s) {
    return value() && dom_.number_float(v, s);
  }
  bool string(json::string_t& v) { return value() && dom_.string(v); }
  bool binary(json::binary_t& v) { return value() && dom_.binary(v); }
  bool start_object(std::size_t n) {
    if (!value() || !enter()) return false;
    path_.push_back({true, 0, ""});
    return dom_.start_object(n);
  }
  bool key(json::string_t& k) {
    path_.back().key = k;
    path_.back().has_key = true;
    return dom_.key(k);
  }
  bool end_object() {
    path_.pop_back();
    return dom_.end_object();
  }
  bool start_array(std::size_t n) {
    if (!value() || !enter()) return false;
    path_.push_back({false, 0, ""});
    return dom_.start_array(n);
  }
  bool end_array() {
    path_.pop_back();
    return dom_.end_array();
  }
  bool parse_error(std::size_t position, const std::string&,
                   const nlohmann::detail::exception& e) {
    error_position = position;
    error_message = e.what();
    return false;
  }

  // The value being read: the member after the last key, or the array
  // element in progress (the innermost array: the next one).
  std::string pointer() const {
    std::string p;
    for (std::size_t i = 0; i < path_.size(); ++i) {
      const Level& l = path_[i];
      if (l.object && !l.has_key) break;
      const bool innermost = i + 1 == path_.size();
      p += "/" + (l.object ? json_pointer_token(l.key)
                           : std::to_string(innermost ? l.count : l.count - 1));
    }
    return p;
  }

  std::size_t error_position = 0;
  std::string error_message;
  bool depth_exceeded = false;
  bool too_many_values = false;

 private:
  struct Level {
    bool object;
    std::size_t count;  // arrays: elements begun so far
    std::string key;    // objects: the last key
    bool has_key = false;
  };
  // A value starts: in an array it is the next element.
  bool value() {
    if (!path_.empty() && !path_.back().object) ++path_.back().count;
    if (++values_ <= kMaxJsonValues) return true;
    error_message = "more than " + std::to_string(kMaxJsonValues) + " values in one file";
    too_many_values = true;
    return false;
  }
  bool enter() {
    if (static_cast<int>(path_.size()) < kMaxJsonDepth) return true;
    error_message = "nesting deeper than " + std::to_string(kMaxJsonDepth) + " levels";
    depth_exceeded = true;
    return false;
  }

  nlohmann::detail::json_sax_dom_parser<json> dom_;
  std::vector<Level> path_;
  std::size_t values_ = 0;
};

}  // namespace

nlohmann::json JsonReader::parse(std::string_view text, const std::string& file) {
  nlohmann::json doc;
  PointerTrackingSax sax(doc);
  bool ok = false;
  try {
    ok = nlohmann::json::sax_parse(text, &sax);
  } catch (const nlohmann::json::exception& e) {
    sax.error_message = e.what();  // the DOM builder's own refusals
  }
  if (ok) return doc;
  const std::string pointer = sax.pointer();
  if (sax.depth_exceeded)
    throw ConfigError(file, pointer, sax.error_message, "flatten the structure");
  if (sax.too_many_values)
    throw ConfigError(file, pointer, sax.error_message,
                      "no model or config needs that many: check that this is the file you meant");
  // Turn the byte offset into line:column, which editors understand.
  std::size_t line = 1, col = 1;
  for (std::size_t i = 0; i + 1 < sax.error_position && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      col = 1;
    } else {
      ++col;
    }
  }
  const std::string where = "(line " + std::to_string(line) + ", column " + std::to_string(col) + ")";
  std::string what = sax.error_message;
  if (what.find("number overflow") != std::string::npos) {
    const auto quote = what.find('\'');
    const std::string number =
        quote == std::string::npos ? "" : what.substr(quote, what.rfind('\'') - quote + 1);
    throw ConfigError(file, pointer,
                      "the number " + number + " " + where + " is too large for a double",
                      "use a number within +-1.8e308 (and within the field's range)");
  }
  if (auto pos = what.find("syntax error"); pos != std::string::npos) what = what.substr(pos);
  throw ConfigError(file, pointer, "not valid JSON " + where + ": " + what,
                    "correct the JSON syntax at that position");
}

std::optional<FileProblem> read_text_file(const std::string& path, std::string& text,
                                          std::size_t max_bytes) {
  const auto limit_text = [&] {
    return max_bytes % (1 << 20) == 0 ? std::to_string(max_bytes >> 20) + " MiB"
                                      : std::to_string(max_bytes) + " bytes";
  };
  const auto os_problem = [&](int err) -> FileProblem {
    switch (err) {
      case ENOENT:
        return {"cannot open the file: no such file", "check the path"};
      case ELOOP:
        return {"cannot open the file: too many levels of symbolic links (a symlink loop?)",
                "point the path at a regular file"};
      case EACCES:
        return {"cannot open the file: permission denied", "check its permissions"};
      default:
        return {std::string("cannot open the file: ") + std::strerror(err),
                "check the path and permissions"};
    }
  };
  // stat first: a device or FIFO is refused before it is opened (opening
  // some devices has effects, reading /dev/zero never ends).
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return os_problem(errno);
  const auto not_regular = [&](mode_t mode) -> std::optional<FileProblem> {
    if (S_ISREG(mode)) return std::nullopt;
    const char* kind = S_ISDIR(mode)   ? "a directory"
                       : S_ISCHR(mode) ? "a character device (like /dev/zero)"
                       : S_ISBLK(mode) ? "a block device"
                       : S_ISFIFO(mode) ? "a FIFO"
                       : S_ISSOCK(mode) ? "a socket"
                                        : "not a regular file";
    return FileProblem{std::string("is ") + kind + ", not a regular file",
                       "give the path of a JSON file"};
  };
  const auto too_large = [&](std::uint64_t size) {
    return FileProblem{"the file is " + std::to_string(size) + " bytes, over the limit of " +
                           limit_text(),
                       "a config, model or template is far smaller: check that this is the "
                       "right file"};
  };
  if (auto p = not_regular(st.st_mode)) return p;
  if (static_cast<std::uint64_t>(st.st_size) > max_bytes) return too_large(st.st_size);
  // O_NONBLOCK: should the path have been swapped for a FIFO since stat, open must not wait.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) return os_problem(errno);
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  if (::fstat(fd, &st) != 0) return os_problem(errno);
  if (auto p = not_regular(st.st_mode)) return p;
  text.clear();
  text.resize(std::min<std::size_t>(static_cast<std::size_t>(st.st_size), max_bytes) + 1);
  std::size_t n = 0;
  for (;;) {
    if (n == text.size()) {
      if (n > max_bytes) return too_large(n);  // it grew since fstat
      text.resize(std::min(max_bytes + 1, 2 * n + 4096));
    }
    const ssize_t got = ::read(fd, text.data() + n, text.size() - n);
    if (got < 0) {
      if (errno == EINTR) continue;
      return FileProblem{std::string("cannot read the file: ") + std::strerror(errno),
                         "check the file"};
    }
    if (got == 0) break;
    n += static_cast<std::size_t>(got);
  }
  if (n > max_bytes) return too_large(n);
  text.resize(n);
  return std::nullopt;
}

nlohmann::json JsonReader::parse_file(const std::string& path) {
  std::string text;
  if (auto p = read_text_file(path, text)) throw ConfigError(path, "", p->problem, p->fix);
  return parse(text, path);
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
  // nlohmann keeps integers over 2^63 - 1 unsigned; read as long long they
  // would wrap negative (2^64 - 1 as -1) and could pass a range check.
  if (value_.is_number_unsigned() &&
      (max < 0 || value_.get<unsigned long long>() > static_cast<unsigned long long>(max)))
    fail("value " + std::to_string(value_.get<unsigned long long>()) + " is out of range",
         "use a value in [" + std::to_string(min) + ", " + std::to_string(max) + "]");
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
