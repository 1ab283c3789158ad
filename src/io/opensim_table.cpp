#include "io/opensim_table.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <optional>
#include <string_view>

#include "io/io_detail.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::io {

namespace {

constexpr std::size_t kMaxHeaderLines = 10000;
constexpr std::size_t kMaxHeaderLineBytes = std::size_t{16} << 20;
// A cell holds a number or a short tuple of them.
constexpr std::size_t kMaxBytesPerCell = 1024;

std::vector<std::string_view> split(std::string_view line, char sep) {
  std::vector<std::string_view> out;
  std::size_t start = 0;
  while (true) {
    const std::size_t at = line.find(sep, start);
    out.push_back(detail::trim(line.substr(start, at == std::string_view::npos ? at : at - start)));
    if (at == std::string_view::npos) return out;
    start = at + 1;
  }
}

// Splits on tabs, or on runs of spaces when a line has no tab (some writers use spaces).
std::vector<std::string_view> fields_of(std::string_view line) {
  if (line.find('\t') != std::string_view::npos) return split(line, '\t');
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && line[i] == ' ') ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ') ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

std::optional<double> number(std::string_view s) {
  s = detail::trim(s);
  double v = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return v;
}

}  // namespace

OpenSimTable read_opensim_table(const std::string& path) {
  std::ifstream in = detail::open_input(path);
  OpenSimTable t;
  std::string line;
  std::size_t line_number = 0;
  bool ended = false;
  const auto next = [&](std::size_t max_bytes) {
    const detail::LineRead got = detail::read_line(in, line, max_bytes);
    if (got == detail::LineRead::end) return false;
    ++line_number;
    if (got == detail::LineRead::too_long) {
      throw FormatError(path, "line " + std::to_string(line_number) + " is longer than " +
                                  std::to_string(max_bytes) + " bytes");
    }
    return true;
  };
  while (line_number < kMaxHeaderLines && next(kMaxHeaderLineBytes)) {
    const std::string_view text = detail::trim(line);
    if (text == "endheader") {
      ended = true;
      break;
    }
    const std::size_t eq = text.find('=');
    if (eq != std::string_view::npos) {
      t.header.emplace_back(detail::trim(text.substr(0, eq)), detail::trim(text.substr(eq + 1)));
    } else if (line_number == 1) {
      t.name = std::string(text);
    }
  }
  if (!ended) {
    throw FormatError(path, "no 'endheader' line in the first " + std::to_string(line_number) +
                                " lines: not an OpenSim table (.sto/.mot)");
  }
  while (next(kMaxHeaderLineBytes) && detail::trim(line).empty()) {
  }
  for (const std::string_view c : fields_of(line)) {
    if (!c.empty()) t.columns.emplace_back(c);
  }
  if (t.columns.empty()) throw FormatError(path, "no column labels after 'endheader'");

  std::size_t tuple = 1;
  double previous_s = 0.0;
  std::size_t bad_rows = 0, first_bad = 0;
  while (next(t.columns.size() * kMaxBytesPerCell + 4096)) {
    if (detail::trim(line).empty()) continue;
    const std::vector<std::string_view> fields = fields_of(line);
    const std::optional<double> time_s = number(fields[0]);
    if (fields.size() != t.columns.size() || !time_s) {
      if (bad_rows++ == 0) first_bad = line_number;
      continue;
    }
    if (t.rows == 0) {
      t.first_time_s = *time_s;
      if (fields.size() > 1) tuple = split(fields[1], ',').size();
    } else if (*time_s <= previous_s && bad_rows++ == 0) {
      first_bad = line_number;
    }
    previous_s = t.last_time_s = *time_s;
    ++t.rows;
  }
  if (bad_rows > 0) {
    t.warnings.push_back(std::to_string(bad_rows) + " rows (the first on line " +
                         std::to_string(first_bad) +
                         ") have a different number of fields than the " +
                         std::to_string(t.columns.size()) +
                         " labels, no time, or a time not after the previous row's");
  }
  t.cell_kind = tuple == 1   ? "numbers"
                : tuple == 4 ? "quaternions (w,x,y,z)"
                : tuple == 3 ? "3-vectors"
                             : std::to_string(tuple) + "-tuples";
  for (const auto& [key, value] : t.header) {
    const std::optional<double> v = number(value);
    if (key == "DataRate" && v && *v > 0.0 && std::isfinite(*v)) {
      t.rate_hz = *v;
      t.rate_source = "from DataRate";
    }
    const auto check = [&](const char* what, std::size_t counted) {
      if (key == what && (!v || *v != static_cast<double>(counted))) {
        t.warnings.push_back(std::string(what) + " is " + value + " but the table has " +
                             std::to_string(counted));
      }
    };
    check("nRows", t.rows);
    check("nColumns", t.columns.size());
  }
  if (t.rate_hz == 0.0 && t.rows > 1 && t.last_time_s > t.first_time_s) {
    t.rate_hz = static_cast<double>(t.rows - 1) / (t.last_time_s - t.first_time_s);
    t.rate_source = "from the time column";
  }
  return t;
}

}  // namespace fabrik::io
