// TRC marker files: 5 header lines (PathFileType; header keys; header values; Frame# Time and
// marker names; X1 Y1 Z1 ...), then one tab-separated row per frame.
#include <charconv>
#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "io/io_detail.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::io {

namespace {
using detail::trim;

std::vector<std::string_view> split_tabs(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  while (true) {
    const std::size_t tab = line.find('\t', start);
    if (tab == std::string_view::npos) {
      fields.push_back(line.substr(start));
      return fields;
    }
    fields.push_back(line.substr(start, tab - start));
    start = tab + 1;
  }
}

// The whole (trimmed) field as a number; from_chars is locale-independent, unlike strtod.
std::optional<double> parse_number(std::string_view s) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return std::nullopt;
  double v = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return v;
}

std::string quoted(std::string_view s) {
  constexpr std::size_t kMax = 40;  // keep messages readable for garbage input
  return "'" + std::string(s.substr(0, kMax)) + (s.size() > kMax ? "...'" : "'");
}

class TrcParser {
 public:
  TrcParser(const std::string& path, std::istream& in) : path_(path), in_(in) {}

  MarkerTrial parse() {
    check_magic();
    std::string line1, keys_line, values_line, names_line, axes_line;
    header_line(line1);
    header_line(keys_line);
    header_line(values_line);
    const std::vector<std::string_view> keys = split_tabs(keys_line);
    const std::vector<std::string_view> values = split_tabs(values_line);
    const auto value_of = [&](std::string_view key) -> std::optional<std::string_view> {
      for (std::size_t i = 0; i < keys.size(); ++i) {
        if (trim(keys[i]) == key) {
          if (i < values.size()) return trim(values[i]);
          return std::string_view();
        }
      }
      return std::nullopt;
    };

    MarkerTrial trial;
    std::optional<std::string_view> rate = value_of("DataRate");
    if (!rate) rate = value_of("CameraRate");
    if (!rate) fail("header: DataRate missing (line 2 names the header fields)");
    const std::optional<double> rate_hz = parse_number(*rate);
    if (!rate_hz || !(*rate_hz > 0.0) || !std::isfinite(*rate_hz)) {
      fail("header: DataRate " + quoted(*rate) + " is not a positive number");
    }
    trial.rate_hz = *rate_hz;
    const std::size_t num_markers = header_count(value_of("NumMarkers"), "NumMarkers");
    const std::size_t num_frames = header_count(value_of("NumFrames"), "NumFrames");
    const std::optional<std::string_view> units = value_of("Units");
    if (!units) fail("header: Units missing");
    double to_m = 0.0;
    if (*units == "mm") {
      to_m = 0.001;
    } else if (*units == "m") {
      to_m = 1.0;
    } else {
      fail("header: Units " + quoted(*units) + " is not supported (expected mm or m)");
    }

    header_line(names_line);
    const std::vector<std::string_view> names = split_tabs(names_line);
    if (trim(names[0]) != "Frame#") fail("line 4: expected 'Frame#' and the marker names");
    for (std::size_t i = 2; i < names.size(); ++i) {
      if (!trim(names[i]).empty()) trial.labels.emplace_back(trim(names[i]));
    }
    if (trial.labels.size() != num_markers) {
      fail("line 4 names " + std::to_string(trial.labels.size()) + " markers but NumMarkers is " +
           std::to_string(num_markers));
    }
    header_line(axes_line);  // X1 Y1 Z1 ...: nothing to learn from it

    const std::size_t columns = 2 + 3 * num_markers;
    const Eigen::Vector3d missing = Eigen::Vector3d::Constant(std::nan(""));
    std::size_t rows = 0;
    std::string line;
    while (next_line(line)) {
      if (trim(line).empty()) continue;  // blank separator and trailing lines
      if (rows == num_frames) {
        fail("line " + std::to_string(line_number_) + ": more data rows than NumFrames (" +
             std::to_string(num_frames) + ")");
      }
      const std::vector<std::string_view> fields = split_tabs(line);
      if (rows == 0) trial.first_frame = frame_number(fields[0]);
      for (std::size_t c = columns; c < fields.size(); ++c) {
        if (!trim(fields[c]).empty()) {
          fail("line " + std::to_string(line_number_) + ": values beyond the " +
               std::to_string(columns) + " columns of Frame#, Time and " +
               std::to_string(num_markers) + " markers");
        }
      }
      for (std::size_t m = 0; m < num_markers; ++m) {
        Eigen::Vector3d p = missing;
        bool complete = true;
        for (std::size_t axis = 0; axis < 3; ++axis) {
          const std::size_t c = 2 + 3 * m + axis;
          const std::string_view field = c < fields.size() ? trim(fields[c]) : std::string_view();
          if (field.empty()) {
            complete = false;  // a short row or an empty field: missing marker
            continue;
          }
          const std::optional<double> v = parse_number(field);
          if (!v) {
            fail("line " + std::to_string(line_number_) + ", column " + std::to_string(c + 1) +
                 ": " + quoted(field) + " is not a number");
          }
          p[static_cast<Eigen::Index>(axis)] = *v * to_m;
        }
        trial.positions_m.push_back(complete && p.allFinite() ? p : missing);
      }
      ++rows;
    }
    if (rows < num_frames) {
      fail("file ends after " + std::to_string(rows) + " of the " + std::to_string(num_frames) +
           " frames NumFrames declares (truncated?)");
    }
    return trial;
  }

 private:
  [[noreturn]] void fail(const std::string& problem) const { throw FormatError(path_, problem); }

  // Rejects binary or other files before reading a possibly huge "line" from them.
  void check_magic() {
    constexpr std::string_view kBom = "\xEF\xBB\xBF", kMagic = "PathFileType";
    char head[15] = {};
    in_.read(head, sizeof head);
    std::string_view got(head, static_cast<std::size_t>(in_.gcount()));
    in_.clear();
    std::streamoff skip = 0;
    if (got.substr(0, kBom.size()) == kBom) {
      got.remove_prefix(kBom.size());
      skip = static_cast<std::streamoff>(kBom.size());
    }
    if (got.substr(0, kMagic.size()) != kMagic) {
      fail("not a TRC file (it does not start with PathFileType)");
    }
    in_.seekg(skip);
  }

  bool next_line(std::string& line) {
    if (!std::getline(in_, line)) return false;
    ++line_number_;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }

  void header_line(std::string& line) {
    if (!next_line(line)) {
      fail("file ends inside the header, at line " + std::to_string(line_number_ + 1) + " of 5");
    }
  }

  std::size_t header_count(std::optional<std::string_view> text, const char* key) const {
    if (!text) fail(std::string("header: ") + key + " missing");
    std::size_t n = 0;
    const auto [end, ec] = std::from_chars(text->data(), text->data() + text->size(), n);
    if (text->empty() || ec != std::errc() || end != text->data() + text->size()) {
      fail(std::string("header: ") + key + " " + quoted(*text) + " is not a whole number");
    }
    return n;
  }

  int frame_number(std::string_view field) const {
    const std::optional<double> v = parse_number(field);
    if (!v || *v != std::floor(*v) || std::abs(*v) > std::numeric_limits<int>::max()) {
      fail("line " + std::to_string(line_number_) + ": frame number " + quoted(trim(field)) +
           " is not a whole number");
    }
    return static_cast<int>(*v);
  }

  const std::string& path_;
  std::istream& in_;
  std::size_t line_number_ = 0;
};

void append_number(std::string& out, double v, int decimals) {
  char buf[400];  // fixed notation of the largest double with 9 decimals fits
  const auto r = decimals < 0
                     ? std::to_chars(buf, buf + sizeof buf, v)
                     : std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
  out.append(buf, r.ptr);
}
}  // namespace

MarkerTrial read_trc(const std::string& path) {
  std::ifstream in = detail::open_input(path);
  return TrcParser(path, in).parse();
}

void write_trc(const std::string& path, const MarkerTrial& trial, const std::string& units) {
  const double from_m = detail::check_trial_for_writing(trial, units, "write_trc");
  for (const std::string& label : trial.labels) {
    if (trim(label).empty() || label.find_first_of("\t\r\n") != std::string::npos) {
      throw std::invalid_argument("write_trc: marker label '" + label +
                                  "' is empty or holds a tab or line break");
    }
  }
  // 1 nm resolution either way: a read-back is well within 1e-6 m.
  const int decimals = units == "mm" ? 6 : 9;
  const std::size_t n = trial.markers(), frames = trial.frames();

  std::string text = "PathFileType\t4\t(X/Y/Z)\t" +
                     std::filesystem::path(path).filename().string() +
                     "\nDataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
                     "OrigDataStartFrame\tOrigNumFrames\n";
  std::string rate;
  append_number(rate, trial.rate_hz, -1);
  text += rate + "\t" + rate + "\t" + std::to_string(frames) + "\t" + std::to_string(n) + "\t" +
          units + "\t" + rate + "\t" + std::to_string(trial.first_frame) + "\t" +
          std::to_string(frames) + "\nFrame#\tTime";
  for (const std::string& label : trial.labels) text += "\t" + label + "\t\t";
  text += "\n\t";
  for (std::size_t m = 1; m <= n; ++m) {
    const std::string k = std::to_string(m);
    text += "\tX" + k + "\tY" + k + "\tZ" + k;
  }
  text += "\n\n";  // OpenSim's files leave line 6 blank

  std::ofstream out = detail::open_output(path);
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  for (std::size_t f = 0; f < frames; ++f) {
    text = std::to_string(static_cast<long long>(trial.first_frame) + static_cast<long long>(f));
    text += '\t';
    append_number(text, trial.time_s(f), -1);  // shortest exact form, not rounded like OpenSim's
    for (std::size_t m = 0; m < n; ++m) {
      const Eigen::Vector3d& p = trial.at(f, m);
      if (!p.allFinite()) {
        text += "\t\t\t";
        continue;
      }
      for (int axis = 0; axis < 3; ++axis) {
        text += '\t';
        append_number(text, p[axis] * from_m, decimals);
      }
    }
    text += '\n';
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
  }
  out.close();
  detail::check_written(out, path);
}

}  // namespace fabrik::io
