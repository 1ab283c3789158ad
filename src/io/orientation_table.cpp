#include "io/orientation_table.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <optional>
#include <string_view>

#include "io/io_detail.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::io {

namespace {

constexpr std::size_t kMaxHeaderLines = 10000;
constexpr std::size_t kMaxHeaderLineBytes = std::size_t{1} << 20;
constexpr std::size_t kMaxCellBytes = 256;  // four numbers and three commas
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::optional<double> parse_number(std::string_view s) {
  s = detail::trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  double v = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return v;
}

// The next tab-separated field of `line` from `pos` (moved past it).
std::string_view next_field(std::string_view line, std::size_t& pos) {
  const std::size_t tab = line.find('\t', pos);
  const std::string_view f = line.substr(pos, tab == std::string_view::npos ? tab : tab - pos);
  pos = tab == std::string_view::npos ? line.size() + 1 : tab + 1;
  return detail::trim(f);
}

// "w,x,y,z" -> the quaternion, or all NaN.
Eigen::Quaterniond parse_cell(std::string_view cell) {
  double v[4];
  std::size_t pos = 0;
  for (int k = 0; k < 4; ++k) {
    const std::size_t comma = cell.find(',', pos);
    if ((k < 3) == (comma == std::string_view::npos)) return Eigen::Quaterniond(kNaN, kNaN, kNaN, kNaN);
    const auto n = parse_number(cell.substr(pos, comma == std::string_view::npos ? comma : comma - pos));
    if (!n) return Eigen::Quaterniond(kNaN, kNaN, kNaN, kNaN);
    v[k] = *n;
    pos = comma + 1;
  }
  return Eigen::Quaterniond(v[0], v[1], v[2], v[3]);
}

}  // namespace

bool is_sto_file(const std::string& path) {
  if (path.size() < 4) return false;
  std::string ext = path.substr(path.size() - 4);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".sto";
}

int OrientationTable::find(const std::string& sensor) const {
  const auto it = std::find(sensors.begin(), sensors.end(), sensor);
  return it == sensors.end() ? -1 : static_cast<int>(it - sensors.begin());
}

void OrientationTable::sample(double t_s, std::span<Eigen::Quaterniond> out) const {
  const std::size_t n = sensors.size();
  const Eigen::Quaterniond missing(kNaN, kNaN, kNaN, kNaN);
  std::fill(out.begin(), out.end(), missing);
  if (rows() == 0 || !std::isfinite(t_s)) return;
  const double half_period_s = rate_hz > 0.0 ? 0.5 / rate_hz : 0.0;
  constexpr double kSameTime_s = 1e-6;
  const auto row_values = [&](std::size_t row) {
    for (std::size_t k = 0; k < n && k < out.size(); ++k) out[k] = at(row, k);
  };
  if (t_s <= time_s.front() + kSameTime_s) {
    if (time_s.front() - t_s <= std::max(half_period_s, kSameTime_s)) row_values(0);
    return;
  }
  if (t_s >= time_s.back() - kSameTime_s) {
    if (t_s - time_s.back() <= std::max(half_period_s, kSameTime_s)) row_values(rows() - 1);
    return;
  }
  const std::size_t hi = static_cast<std::size_t>(
      std::upper_bound(time_s.begin(), time_s.end(), t_s) - time_s.begin());
  const std::size_t lo = hi - 1;
  if (t_s - time_s[lo] <= kSameTime_s) return row_values(lo);
  if (time_s[hi] - t_s <= kSameTime_s) return row_values(hi);
  const double f = (t_s - time_s[lo]) / (time_s[hi] - time_s[lo]);
  for (std::size_t k = 0; k < n && k < out.size(); ++k) {
    const Eigen::Quaterniond& a = at(lo, k);
    const Eigen::Quaterniond& b = at(hi, k);
    if (!a.coeffs().allFinite() || !b.coeffs().allFinite() || a.norm() < 0.5 || b.norm() < 0.5)
      continue;
    out[k] = a.normalized().slerp(f, b.normalized());
  }
}

OrientationTable read_orientation_table(const std::string& path) {
  std::ifstream in = detail::open_input(path);
  OrientationTable t;
  std::string line;
  std::size_t line_number = 0;
  const auto next = [&](std::size_t max_bytes) {
    const detail::LineRead got = detail::read_line(in, line, max_bytes);
    if (got == detail::LineRead::end) return false;
    ++line_number;
    if (got == detail::LineRead::too_long)
      throw FormatError(path, "line " + std::to_string(line_number) + " is longer than " +
                                  std::to_string(max_bytes) + " bytes");
    return true;
  };
  bool ended = false;
  std::string data_type;
  double data_rate = 0.0;
  while (line_number < kMaxHeaderLines && next(kMaxHeaderLineBytes)) {
    const std::string_view text = detail::trim(line);
    if (text == "endheader") {
      ended = true;
      break;
    }
    const std::size_t eq = text.find('=');
    if (eq == std::string_view::npos) continue;
    const std::string_view key = detail::trim(text.substr(0, eq));
    const std::string_view value = detail::trim(text.substr(eq + 1));
    if (key == "DataType") data_type = value;
    if (key == "DataRate")
      if (const auto v = parse_number(value); v && *v > 0.0 && std::isfinite(*v)) data_rate = *v;
  }
  if (!ended)
    throw FormatError(path, "no 'endheader' line in the first " + std::to_string(line_number) +
                                " lines: not an OpenSim table (.sto)");
  if (!data_type.empty() && data_type != "Quaternion")
    throw FormatError(path, "DataType=" + data_type +
                                ": not orientations. Fix: give a quaternion table "
                                "(DataType=Quaternion, cells w,x,y,z), as OpenSense writes");
  while (next(kMaxHeaderLineBytes) && detail::trim(line).empty()) {
  }
  {
    std::size_t pos = 0;
    const std::string_view labels = line;
    for (bool first = true; pos <= labels.size(); first = false) {
      const std::string_view f = next_field(labels, pos);
      if (!first) t.sensors.emplace_back(f);
    }
  }
  if (t.sensors.empty() || std::any_of(t.sensors.begin(), t.sensors.end(),
                                        [](const std::string& s) { return s.empty(); }))
    throw FormatError(path, "line " + std::to_string(line_number) +
                                ": expected the labels 'time' and one per sensor, tab-separated");
  const std::size_t n = t.sensors.size();
  std::size_t bad_rows = 0, first_bad = 0, bad_cells = 0, not_unit = 0;
  while (next(n * kMaxCellBytes + 4096)) {
    if (detail::trim(line).empty()) continue;
    const std::string_view row = line;
    std::size_t pos = 0;
    const std::optional<double> time = parse_number(next_field(row, pos));
    const std::size_t fields =
        1 + static_cast<std::size_t>(std::count(row.begin(), row.end(), '\t'));
    if (!time || !std::isfinite(*time) || fields != n + 1 ||
        (!t.time_s.empty() && !(*time > t.time_s.back()))) {
      if (bad_rows++ == 0) first_bad = line_number;
      continue;
    }
    t.time_s.push_back(*time);
    for (std::size_t k = 0; k < n; ++k) {
      const std::string_view cell = next_field(row, pos);
      const Eigen::Quaterniond q = parse_cell(cell);
      if (!q.coeffs().allFinite()) {
        ++bad_cells;
      } else if (std::abs(q.norm() - 1.0) > 0.01) {
        ++not_unit;
      }
      t.q.push_back(q);
    }
  }
  if (t.rows() == 0)
    throw FormatError(path, "no usable data row after the labels (" + std::to_string(bad_rows) +
                                " rows with another number of fields than " +
                                std::to_string(n + 1) + " or no time)");
  if (bad_rows > 0)
    t.warnings.push_back(std::to_string(bad_rows) + " rows (the first on line " +
                         std::to_string(first_bad) + ") have another number of fields than the " +
                         std::to_string(n + 1) +
                         " labels, no time, or a time not after the previous row's: left out");
  if (bad_cells > 0)
    t.warnings.push_back(std::to_string(bad_cells) +
                         " cells are not four numbers w,x,y,z: read as missing");
  if (not_unit > 0)
    t.warnings.push_back(std::to_string(not_unit) +
                         " quaternions are not of unit length (within 0.01): tracked as missing");
  if (data_rate > 0.0) {
    t.rate_hz = data_rate;
    t.rate_source = "from DataRate";
  } else if (t.rows() > 1) {
    t.rate_hz = static_cast<double>(t.rows() - 1) / (t.time_s.back() - t.time_s.front());
    t.rate_source = "from the time column";
  }
  return t;
}

}  // namespace fabrik::io
