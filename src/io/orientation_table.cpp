#include "io/orientation_table.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/ascii_case.hpp"
#include "common/format_number.hpp"
#include "io/marker_trial.hpp"
#include "io/opensim_table.hpp"

namespace fabrik::io {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Times this close are one instant: a row's own values, no interpolation.
constexpr double kSameTime_s = 1e-6;
}  // namespace

bool is_sto_file(const std::string& path) {
  if (path.size() < 4) return false;
  return iequals(std::string_view(path).substr(path.size() - 4), ".sto");
}

int OrientationTable::find(const std::string& sensor) const {
  const auto it = std::find(sensors.begin(), sensors.end(), sensor);
  return it == sensors.end() ? -1 : static_cast<int>(it - sensors.begin());
}

bool OrientationTable::covers(double t_s) const {
  if (rows() == 0 || !std::isfinite(t_s)) return false;
  const double reach_s = std::max(rate_hz > 0.0 ? 0.5 / rate_hz : 0.0, kSameTime_s);
  return t_s >= time_s.front() - reach_s && t_s <= time_s.back() + reach_s;
}

void OrientationTable::sample(double t_s, std::span<Eigen::Quaterniond> out) const {
  const std::size_t n = sensors.size();
  const Eigen::Quaterniond missing(kNaN, kNaN, kNaN, kNaN);
  std::fill(out.begin(), out.end(), missing);
  if (!covers(t_s)) return;
  const auto row_values = [&](std::size_t row) {
    for (std::size_t k = 0; k < n && k < out.size(); ++k) out[k] = at(row, k);
  };
  if (t_s <= time_s.front() + kSameTime_s) return row_values(0);
  if (t_s >= time_s.back() - kSameTime_s) return row_values(rows() - 1);
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
  // A sensor's dropout is its cell's only: the row's other sensors are kept.
  const OpenSimTable src = read_opensim_table(path, {.bad_cells_missing = true});
  const std::string data_type = src.header_value("DataType");
  if (!data_type.empty() && data_type != "Quaternion")
    throw FormatError(path, "DataType=" + data_type +
                                ": not orientations. Fix: give a quaternion table "
                                "(DataType=Quaternion, cells w,x,y,z), as OpenSense writes");
  if (src.cell_width == 4 && src.columns.size() >= 2 && src.rows == 0)
    throw FormatError(path,
                      "has no row that could be read" +
                          (src.warnings.empty() ? std::string() : ": " + src.warnings.front()));
  if (src.cell_width != 4 || src.columns.size() < 2 || src.rows == 0)
    throw FormatError(path, "holds " + src.cell_kind + " in " +
                                std::to_string(src.columns.size()) + " columns and " +
                                std::to_string(src.rows) +
                                " rows, not quaternions. Fix: give a table whose cells are "
                                "w,x,y,z (DataType=Quaternion), as OpenSense writes");
  OrientationTable t;
  t.sensors.assign(src.columns.begin() + 1, src.columns.end());
  t.time_s = src.time_s;
  t.rate_hz = src.rate_hz;
  t.rate_source = src.rate_source;
  t.warnings = src.warnings;
  std::size_t not_unit = 0, all_nan = 0, first_nan_row = 0, first_nan_column = 0;
  t.q.reserve(src.rows * t.sensors.size());
  for (std::size_t r = 0; r < src.rows; ++r)
    for (std::size_t c = 1; c < src.columns.size(); ++c) {
      const Eigen::Quaterniond q = src.quaternion(r, c);
      if (q.coeffs().array().isNaN().all()) {  // "nan", or not four numbers (said above)
        if (all_nan++ == 0) first_nan_row = r, first_nan_column = c;
        t.q.emplace_back(kNaN, kNaN, kNaN, kNaN);
      } else if (!q.coeffs().allFinite() || std::abs(q.norm() - 1.0) > 0.01) {
        ++not_unit;
        t.q.emplace_back(kNaN, kNaN, kNaN, kNaN);
      } else {
        t.q.push_back(q);
      }
    }
  // OpenSense writes nan for a sensor's dropout: missing as asked, but said, as other gaps are.
  if (all_nan > src.bad_cells)
    t.warnings.push_back(std::to_string(all_nan - src.bad_cells) + " cells are nan (" +
                         (src.bad_cells == 0
                              ? "the first at " + format_number("%.9g", src.time_s[first_nan_row]) +
                                    " s, column " + src.columns[first_nan_column]
                              : "besides the cells above") +
                         "): missing for their sensor only");
  if (not_unit > 0)
    t.warnings.push_back(std::to_string(not_unit) +
                         " quaternions are not finite or not of unit length (within 0.01): "
                         "missing for their sensor only");
  return t;
}

void check_time_overlap(const MarkerTrial& trial, const std::string& trial_path,
                        const OrientationTable& table, const std::string& table_path,
                        std::vector<std::string>& warnings) {
  const std::size_t frames = trial.frames();
  if (frames == 0 || table.rows() == 0) return;
  std::size_t outside = 0;
  for (std::size_t f = 0; f < frames; ++f)
    if (!table.covers(trial.file_time_s(f))) ++outside;
  if (outside == 0) return;
  const auto span = [](double first_s, double last_s) {
    return format_number("%.9g", first_s) + " to " + format_number("%.9g", last_s) + " s";
  };
  const std::string spans = "the markers (" + trial_path + ") span " +
                            span(trial.file_time_s(0), trial.file_time_s(frames - 1)) +
                            ", the orientations " + span(table.time_s.front(), table.time_s.back());
  // Joined on time, a table beside the trial would leave every frame without orientations:
  // a markers-only result that looks like a joined one.
  if (outside == frames)
    throw FormatError(table_path,
                      "no marker frame falls within its time span: " + spans +
                          ". Fix: give the orientations recorded with this trial, or make the "
                          "table's time column count from the same start as the trial's (the "
                          "two are joined on their times)");
  warnings.push_back(std::to_string(outside) + " of " + std::to_string(frames) +
                     " marker frames fall outside its time span (" + spans +
                     "): they are tracked without orientations");
}

}  // namespace fabrik::io
