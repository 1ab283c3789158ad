#include "io/opensim_table.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string_view>

#include "common/ascii_case.hpp"
#include "io/io_detail.hpp"
#include "io/marker_trial.hpp"
#include "io/output_file.hpp"

namespace fabrik::io {

namespace {

constexpr std::size_t kMaxHeaderLines = 10000;
constexpr std::size_t kMaxTableHeaderLineBytes = std::size_t{16} << 20;
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

// The whole field as a number (from_chars: locale-independent; reads nan and inf).
std::optional<double> number(std::string_view s) {
  s = detail::trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  double v = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return v;
}

// The numbers of one cell appended to `out`; their count, 0 if one is not a number.
std::size_t read_cell(std::string_view cell, std::vector<double>& out) {
  std::size_t n = 0;
  for (const std::string_view part : split(cell, ',')) {
    const std::optional<double> v = number(part);
    if (!v) return 0;
    out.push_back(*v);
    ++n;
  }
  return n;
}

std::string cell_kind(std::size_t width) {
  return width == 1   ? "numbers"
         : width == 4 ? "quaternions (w,x,y,z)"
         : width == 3 ? "3-vectors"
                      : std::to_string(width) + "-tuples";
}

std::string number_text(double v, const char* format) {
  if (std::isnan(v)) return "NaN";
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

}  // namespace

int OpenSimTable::find(const std::string& label) const {
  const auto it = std::find(columns.begin(), columns.end(), label);
  return it == columns.end() ? -1 : static_cast<int>(it - columns.begin());
}

std::string OpenSimTable::header_value(const std::string& key) const {
  for (const auto& [k, v] : header)
    if (k == key) return v;
  return {};
}

bool OpenSimTable::in_degrees() const {
  return iequals(header_value("inDegrees"), "yes");
}

Eigen::Quaterniond OpenSimTable::quaternion(std::size_t row, std::size_t column) const {
  if (cell_width != 4) throw std::logic_error("OpenSimTable::quaternion: cells are not w,x,y,z");
  return {at(row, column, 0), at(row, column, 1), at(row, column, 2), at(row, column, 3)};
}

void OpenSimTable::add_row(double time, const std::vector<double>& cells) {
  const std::size_t expected = (columns.empty() ? 0 : columns.size() - 1) * cell_width;
  if (cells.size() != expected)
    throw std::invalid_argument("OpenSimTable::add_row: " + std::to_string(cells.size()) +
                                " numbers, expected " + std::to_string(expected));
  if (rows == 0) first_time_s = time;
  last_time_s = time;
  ++rows;
  time_s.push_back(time);
  values.insert(values.end(), cells.begin(), cells.end());
}

OpenSimTable coordinates_table(const std::vector<std::string>& labels, bool in_degrees) {
  OpenSimTable t;
  t.name = "Coordinates";
  t.header = {{"version", "1"},
              {"nRows", "0"},
              {"nColumns", std::to_string(labels.size() + 1)},
              {"inDegrees", in_degrees ? "yes" : "no"}};
  t.comments = {"Units are S.I. units (second, meters, Newtons, ...)"};
  if (in_degrees) t.comments.push_back("Angles are in degrees.");
  t.columns.push_back("time");
  t.columns.insert(t.columns.end(), labels.begin(), labels.end());
  t.cell_kind = cell_kind(1);
  return t;
}

OpenSimTable read_opensim_table(const std::string& path, const OpenSimReadOptions& options) {
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
  while (line_number < kMaxHeaderLines && next(kMaxTableHeaderLineBytes)) {
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
    } else if (!text.empty()) {
      t.comments.emplace_back(text);
    }
  }
  if (!ended) {
    throw FormatError(path, "no 'endheader' line in the first " + std::to_string(line_number) +
                                " lines: not an OpenSim table (.sto/.mot)");
  }
  while (next(kMaxTableHeaderLineBytes) && detail::trim(line).empty()) {
  }
  for (const std::string_view c : fields_of(line)) {
    if (!c.empty()) t.columns.emplace_back(c);
  }
  if (t.columns.empty()) throw FormatError(path, "no column labels after 'endheader'");

  // A quaternion table says so: its cells are 4 wide before any is read, so a first row whose
  // cell is "nan" or empty is a missing cell (or a row left out), not the table's width.
  std::size_t width = t.header_value("DataType") == "Quaternion" ? 4 : 0;
  double previous_s = 0.0;
  std::size_t bad_rows = 0, first_bad = 0, unordered_rows = 0, first_unordered = 0;
  std::size_t back_rows = 0, first_back = 0, line_before_back = 0, previous_line = 0;
  double back_s = 0.0, before_back_s = 0.0;
  std::size_t bad_cells = 0, first_bad_cell = 0;
  std::string first_bad_column;
  // Every row with a time, kept or not: the rate from the time column counts the frames a
  // row left out for a bad cell still took, and spans rows out of order.
  std::size_t timed_rows = 0;
  double earliest_s = INFINITY, latest_s = -INFINITY;
  std::vector<double> cells;
  const auto bad = [&] {
    if (bad_rows++ == 0) first_bad = line_number;
  };
  while (next(t.columns.size() * kMaxBytesPerCell + 4096)) {
    if (detail::trim(line).empty()) continue;
    std::vector<std::string_view> fields = fields_of(line);
    // A tab ending every row (some exporters) is no empty last cell: the labels skip it too.
    if (fields.size() == t.columns.size() + 1 && fields.back().empty()) fields.pop_back();
    const std::optional<double> time_s = number(fields[0]);
    if (time_s && std::isfinite(*time_s)) {
      ++timed_rows;
      earliest_s = std::min(earliest_s, *time_s);
      latest_s = std::max(latest_s, *time_s);
    }
    if (fields.size() != t.columns.size() || !time_s || !std::isfinite(*time_s)) {
      bad();
      continue;
    }
    cells.clear();
    bool usable = true;
    for (std::size_t c = 1; c < fields.size() && usable; ++c) {
      const std::size_t before = cells.size();
      const std::size_t n = read_cell(fields[c], cells);
      if (width == 0) width = n;
      usable = n != 0 && n == width;
      if (!usable && options.bad_cells_missing && width != 0) {
        cells.resize(before);
        cells.insert(cells.end(), width, std::numeric_limits<double>::quiet_NaN());
        if (bad_cells++ == 0) first_bad_cell = line_number, first_bad_column = t.columns[c];
        usable = true;
      }
    }
    if (!usable) {
      bad();
      continue;
    }
    if (t.rows > 0 && *time_s < previous_s && back_rows++ == 0) {
      first_back = line_number, back_s = *time_s;
      line_before_back = previous_line, before_back_s = previous_s;
    } else if (t.rows > 0 && *time_s == previous_s && unordered_rows++ == 0) {  // kept, but said
      first_unordered = line_number;
    }
    previous_s = *time_s;
    previous_line = line_number;
    t.cell_width = width;
    t.add_row(*time_s, cells);
  }
  t.cell_width = width == 0 ? 1 : width;  // a quaternion table without rows says 4 too
  if (bad_rows > 0) {
    t.warnings.push_back(std::to_string(bad_rows) + " rows left out (the first on line " +
                         std::to_string(first_bad) + "): a different number of fields than the " +
                         std::to_string(t.columns.size()) +
                         " labels, no time, or a cell that is not a number");
  }
  if (unordered_rows > 0) {
    t.warnings.push_back(std::to_string(unordered_rows) + " rows kept (the first on line " +
                         std::to_string(first_unordered) + ") whose time is the previous row's");
  }
  if (back_rows > 0) {
    const std::string what = "the time column goes back in time at " + std::to_string(back_rows) +
                             (back_rows == 1 ? " row" : " rows") + " (the first at line " +
                             std::to_string(first_back) + ": " + number_text(back_s, "%.9g") +
                             " s after " + number_text(before_back_s, "%.9g") + " s at line " +
                             std::to_string(line_before_back) + ")";
    if (options.refuse_time_back)
      throw FormatError(path, what +
                                  ". Fix: put the rows in time order, or export the table "
                                  "again: OpenSim refuses a time column that goes back");
    t.warnings.push_back(what + ": rows kept in the file's order");
  }
  t.bad_cells = bad_cells;
  if (bad_cells > 0) {
    t.warnings.push_back(std::to_string(bad_cells) + " cells (the first on line " +
                         std::to_string(first_bad_cell) + ", column " + first_bad_column +
                         ") are not " + std::to_string(width) +
                         " numbers: read as missing, their rows kept");
  }
  t.cell_kind = cell_kind(t.cell_width);
  for (const auto& entry : t.header) {
    // Named references, not a structured binding: the lambda below captures
    // them (clang before 16 cannot capture structured bindings).
    const std::string& key = entry.first;
    const std::string& value = entry.second;
    const std::optional<double> v = number(value);
    if (key == "DataRate" && v && plausible_frame_rate(*v)) {
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
  if (t.rate_hz == 0.0 && timed_rows > 1 && latest_s > earliest_s) {
    t.rate_hz = static_cast<double>(timed_rows - 1) / (latest_s - earliest_s);
    t.rate_source = "from the time column";
  }
  return t;
}

void write_opensim_table(const std::string& path, const OpenSimTable& t) {
  if (t.columns.empty() || t.cell_width < 1)
    throw std::invalid_argument("write_opensim_table: no columns (time first) or cell_width 0");
  const std::size_t data_columns = t.columns.size() - 1;
  if (t.time_s.size() != t.rows || t.values.size() != t.rows * data_columns * t.cell_width)
    throw std::invalid_argument("write_opensim_table: " + std::to_string(t.values.size()) +
                                " values and " + std::to_string(t.time_s.size()) + " times for " +
                                std::to_string(t.rows) + " rows of " +
                                std::to_string(data_columns) + " columns");
  for (const std::string& l : t.columns)
    if (l.empty() || l.find_first_of("\t\r\n, ") != std::string::npos)
      throw std::invalid_argument("write_opensim_table: label '" + l +
                                  "' is empty or holds a space, tab, comma or line break");
  std::ofstream out = open_output_file(path);
  if (!t.name.empty()) out << t.name << '\n';
  for (const auto& entry : t.header) {
    // Named references, not a structured binding: the lambda below captures
    // them (clang before 16 cannot capture structured bindings).
    const std::string& key = entry.first;
    const std::string& value = entry.second;
    out << key << '=';
    if (key == "nRows")
      out << t.rows;
    else if (key == "nColumns")
      out << t.columns.size();
    else
      out << value;
    out << '\n';
  }
  if (!t.comments.empty()) {
    out << '\n';
    for (const std::string& c : t.comments) out << c << '\n';
    out << '\n';
  }
  out << "endheader\n";
  for (std::size_t c = 0; c < t.columns.size(); ++c) out << (c ? "\t" : "") << t.columns[c];
  out << '\n';
  const char* format = t.cell_width == 1 ? "%.8f" : "%.12g";
  for (std::size_t r = 0; r < t.rows; ++r) {
    out << number_text(t.time_s[r], "%.8f");
    for (std::size_t c = 1; c <= data_columns; ++c) {
      out << '\t';
      for (std::size_t k = 0; k < t.cell_width; ++k)
        out << (k ? "," : "") << number_text(t.at(r, c, k), format);
    }
    out << '\n';
  }
  finish_output_file(out, path);
}

}  // namespace fabrik::io
