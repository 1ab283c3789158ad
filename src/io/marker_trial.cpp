#include "io/marker_trial.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string_view>
#include <system_error>
#include <unordered_map>

#include "common/ascii_case.hpp"
#include "io/io_detail.hpp"

namespace fabrik::io {

int MarkerTrial::find(const std::string& label) const {
  const auto it = std::find(labels.begin(), labels.end(), label);
  return it == labels.end() ? -1 : static_cast<int>(it - labels.begin());
}

MarkerTrial read_trial(const std::string& path, const ReadOptions& options) {
  const std::string ext = ascii_lower(std::filesystem::path(path).extension().string());
  if (ext == ".trc") return read_trc(path, options);
  if (ext == ".c3d") return read_c3d(path, options);
  throw FormatError(path, "unknown file type '" + ext + "' (expected .trc or .c3d)");
}

void require_marker_data(const MarkerTrial& trial, const std::string& path) {
  if (trial.markers() > 0 && trial.frames() > 0) return;
  const RecordingFacts& f = trial.source;
  if (trial.markers() > 0) {
    throw FormatError(path, "the file has " + std::to_string(trial.markers()) +
                                " markers but no frames of 3D data");
  }
  std::vector<std::string> other;
  if (f.analog_channels > 0) {
    char rate[32];
    std::snprintf(rate, sizeof rate, "%g", f.analog_rate_hz);
    other.push_back(std::to_string(f.analog_channels) + " analog channel" +
                    (f.analog_channels == 1 ? "" : "s") +
                    (f.analog_rate_hz > 0.0 ? std::string(" at ") + rate + " Hz" : ""));
  }
  if (f.rotations > 0) {
    other.push_back(std::to_string(f.rotations) + " rotation" + (f.rotations == 1 ? "" : "s"));
  }
  std::string holds = "no other data either";
  if (!other.empty()) {
    holds = other[0] + (other.size() > 1 ? " and " + other[1] : "") + " over " +
            std::to_string(f.frames) + " frame" + (f.frames == 1 ? "" : "s");
  }
  throw FormatError(path, "the file has no 3D marker data; it has " + holds +
                              ". Fix: give a recording with labelled markers (check it with "
                              "`fabrik info`)");
}

namespace detail {

std::ifstream open_input(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status)) throw FormatError(path, "file not found");
  if (!std::filesystem::is_regular_file(status)) throw FormatError(path, "not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FormatError(path, "cannot open the file for reading");
  return in;
}

double check_trial_for_writing(const MarkerTrial& trial, const std::string& units,
                               const char* writer) {
  const std::string what = std::string(writer) + ": ";
  if (!(trial.rate_hz > 0.0) || !std::isfinite(trial.rate_hz)) {
    throw std::invalid_argument(what + "rate_hz must be positive and finite");
  }
  if (trial.labels.empty() ? !trial.positions_m.empty()
                           : trial.positions_m.size() % trial.labels.size() != 0) {
    throw std::invalid_argument(what + "positions_m.size() (" +
                                std::to_string(trial.positions_m.size()) +
                                ") is not a multiple of the number of labels (" +
                                std::to_string(trial.labels.size()) + ")");
  }
  if (units == "mm") return 1000.0;
  if (units == "m") return 1.0;
  throw std::invalid_argument(what + "units must be \"mm\" or \"m\", not \"" + units + "\"");
}

std::string_view trim(std::string_view s) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\0'; };
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

LineRead read_line(std::istream& in, std::string& line, std::size_t max_bytes) {
  line.clear();
  std::streambuf* buf = in.rdbuf();
  int c = buf->sbumpc();
  if (c == std::char_traits<char>::eof()) return LineRead::end;
  for (; c != std::char_traits<char>::eof() && c != '\n'; c = buf->sbumpc()) {
    if (line.size() == max_bytes) return LineRead::too_long;
    line.push_back(static_cast<char>(c));
  }
  if (!line.empty() && line.back() == '\r') line.pop_back();
  return c == '\n' ? LineRead::line : LineRead::unterminated;
}

std::optional<double> metres_per_unit(std::string_view units) {
  const std::string u = ascii_lower(trim(units));
  if (u == "mm" || u == "millimeter" || u == "millimeters" || u == "millimetre" ||
      u == "millimetres") {
    return 0.001;
  }
  if (u == "cm" || u == "centimeter" || u == "centimeters" || u == "centimetre" ||
      u == "centimetres") {
    return 0.01;
  }
  if (u == "m" || u == "meter" || u == "meters" || u == "metre" || u == "metres") return 1.0;
  return std::nullopt;
}

void check_repeated_labels(MarkerTrial& trial, const std::string& path, const ReadOptions& options,
                           const std::string& where, const std::string& numbering,
                           std::size_t (*number)(std::size_t), const std::string& fix) {
  std::unordered_map<std::string_view, std::size_t> first;
  std::vector<RepeatedLabel>& repeated = trial.source.repeated_labels;
  for (std::size_t m = 0; m < trial.labels.size(); ++m) {
    const std::string& label = trial.labels[m];
    if (label.empty()) continue;  // no model marker is named "": nothing is ambiguous
    const auto [it, fresh] = first.emplace(label, m);
    if (!fresh) repeated.push_back({label, number(it->second), number(m)});
  }
  for (const RepeatedLabel& r : repeated) {
    const std::string what = "marker '" + r.label + "' labels " + numbering + " " +
                             std::to_string(r.first) + " and " + std::to_string(r.second);
    if (options.refuse_ambiguous) {
      const std::size_t more = repeated.size() - 1;
      throw FormatError(path, where + ": " + what + ": which of them is the marker is ambiguous" +
                                  (more ? " (and " + std::to_string(more) + " more repeated " +
                                              (more == 1 ? "label" : "labels") + ")"
                                        : std::string()) +
                                  ". Fix: " + fix + "; `fabrik info` lists every repetition");
    }
    trial.warnings.push_back(where + ": " + what +
                             ": ambiguous, `fabrik solve` refuses the file. "
                             "Fix: " +
                             fix);
  }
}

void warn_about_zeros(MarkerTrial& trial, const ReadOptions& options) {
  const std::vector<std::size_t>& zeros = trial.source.zero_samples;
  std::size_t samples = 0, markers = 0, worst = 0;
  for (std::size_t m = 0; m < zeros.size(); ++m) {
    samples += zeros[m];
    markers += zeros[m] > 0 ? 1 : 0;
    if (zeros[m] > zeros[worst]) worst = m;
  }
  if (samples == 0) return;
  trial.warnings.push_back(
      std::to_string(samples) + " sample" + (samples == 1 ? "" : "s") + " of " +
      std::to_string(markers) + " marker" + (markers == 1 ? "" : "s") +
      " are exactly (0, 0, 0) (most: " + trial.labels[worst] + ", " +
      std::to_string(zeros[worst]) + " of " + std::to_string(trial.frames()) + " frames): " +
      (options.zeros_are_missing
           ? "read as missing, as exporters write them for markers not seen (keep-zeros "
             "reads them as positions)"
           : "kept as positions at the origin (keep-zeros)"));
}

void warn_about_units(MarkerTrial& trial, const std::string& unit_field) {
  // Bounds far outside any marker set on a person (a hand's cluster spans 50 mm, a gym 30 m),
  // so a right file is never told its unit is wrong.
  constexpr double kSmallest_m = 0.02, kLargest_m = kLargestMarkerSpan_m;
  constexpr std::size_t kFramesLooked = 200;  // spread over the trial: cheap on long ones
  const std::size_t frames = trial.frames();
  const auto median = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  // Per frame the bounding box's diagonal (for the warning), and twice the markers' median
  // distance from their per-axis median (for typical_span_m: one glitching marker 150 m
  // out, or a few frames of 1e9, leave it a body's size).
  std::vector<double> spans_m, spreads_m, axis[3], distances_m;
  std::vector<Eigen::Vector3d> points_m;
  for (std::size_t k = 0; k < std::min(frames, kFramesLooked); ++k) {
    const std::size_t f = k * frames / std::min(frames, kFramesLooked);
    Eigen::Vector3d low = Eigen::Vector3d::Constant(INFINITY), high = -low;
    points_m.clear();
    for (std::size_t m = 0; m < trial.markers(); ++m) {
      const Eigen::Vector3d& p_m = trial.at(f, m);
      if (!p_m.allFinite()) continue;
      low = low.cwiseMin(p_m);
      high = high.cwiseMax(p_m);
      // Exact zeros kept (keep-zeros) are markers not seen, not a body's: half of them at the
      // origin made the spread 0 and the file "metres labelled mm".
      if (p_m != Eigen::Vector3d::Zero()) points_m.push_back(p_m);
    }
    if (points_m.size() < 3) continue;
    spans_m.push_back((high - low).norm());
    Eigen::Vector3d centre_m;
    for (int a = 0; a < 3; ++a) {
      axis[a].clear();
      for (const Eigen::Vector3d& p_m : points_m) axis[a].push_back(p_m[a]);
      centre_m[a] = median(axis[a]);
    }
    distances_m.clear();
    for (const Eigen::Vector3d& p_m : points_m) distances_m.push_back((p_m - centre_m).norm());
    spreads_m.push_back(2.0 * median(distances_m));
  }
  if (spans_m.empty()) return;
  const double span_m = median(spans_m);
  const double spread_m = median(spreads_m);
  trial.source.typical_span_m = spread_m;
  // The commands refuse on the spread (robust to a glitching marker); the bounding box, wider,
  // only warns.
  const bool refused = spread_m < kSmallestMarkerSpan_m || spread_m > kLargestMarkerSpan_m;
  if (!refused && span_m >= kSmallest_m && span_m <= kLargest_m) return;
  const bool small = refused ? spread_m < kSmallestMarkerSpan_m : span_m < kSmallest_m;
  const std::optional<double> m_per_unit = metres_per_unit(trial.source.units);
  const std::string unit = m_per_unit ? trial.source.units : "m";
  char figure[48];
  std::snprintf(figure, sizeof figure, "%.4g %s",
                (refused ? spread_m : span_m) / m_per_unit.value_or(1.0), unit.c_str());
  const std::string bound =
      small ? (refused ? "less than 10 mm" : "less than 20 mm") : "more than 100 m";
  std::string message = std::string(refused ? "the markers spread over " : "the markers span ") +
                        figure + " in a typical frame (" + bound +
                        ", where a body spans about a metre): is the unit right? Fix: correct " +
                        unit_field +
                        (small ? " (metres labelled mm read 1000 times too small)"
                               : " (mm labelled m read 1000 times too large)");
  trial.warnings.push_back(message);
  if (refused) trial.source.unit_problem = std::move(message);
}

}  // namespace detail
}  // namespace fabrik::io
