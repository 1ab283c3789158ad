#include "angles.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "offline/solve_trial.hpp"

namespace fabrik::eval {

namespace {

// Removes 2 pi jumps between consecutive angles.
void unwrap(std::vector<double>& a) {
  for (std::size_t i = 1; i < a.size(); ++i)
    a[i] = a[i - 1] + std::remainder(a[i] - a[i - 1], 2.0 * std::numbers::pi);
}

double mean(const std::vector<double>& v) {
  double sum = 0.0;
  for (double x : v) sum += x;
  return v.empty() ? 0.0 : sum / static_cast<double>(v.size());
}

double range(const std::vector<double>& v) {
  if (v.empty()) return 0.0;
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return *hi - *lo;
}

double pearson(const std::vector<double>& a, const std::vector<double>& b) {
  const double ma = mean(a), mb = mean(b);
  double sab = 0.0, saa = 0.0, sbb = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  // A series that does not move (a locked coordinate: OpenSim writes its
  // rounding noise, ~1e-8 rad) has no correlation.
  constexpr double kFlatSi = 1e-6;  // radians or metres
  if (range(a) < kFlatSi || range(b) < kFlatSi || saa <= 0.0 || sbb <= 0.0)
    return std::numeric_limits<double>::quiet_NaN();
  return sab / std::sqrt(saa * sbb);
}

void compare(CoordinateComparison& c) {
  if (c.kind == CoordinateKind::rotation) {
    unwrap(c.fabrik_si);
    unwrap(c.reference_si);
    // Whole turns between the two are a labelling matter, not an error.
    const double turns =
        std::round((mean(c.fabrik_si) - mean(c.reference_si)) / (2.0 * std::numbers::pi));
    for (double& v : c.fabrik_si) v -= turns * 2.0 * std::numbers::pi;
  }
  const std::size_t n = c.fabrik_si.size();
  c.samples = n;
  std::vector<double> d(n);
  for (std::size_t i = 0; i < n; ++i) d[i] = c.fabrik_si[i] - c.reference_si[i];
  c.offset_si = mean(d);
  double sq = 0.0, sq_centered = 0.0;
  for (double x : d) sq += x * x, sq_centered += (x - c.offset_si) * (x - c.offset_si);
  c.rms_si = n ? std::sqrt(sq / static_cast<double>(n)) : 0.0;
  c.rms_centered_si = n ? std::sqrt(sq_centered / static_cast<double>(n)) : 0.0;
  c.pearson_r = pearson(c.fabrik_si, c.reference_si);
  c.range_fabrik_si = range(c.fabrik_si);
  c.range_reference_si = range(c.reference_si);
}

}  // namespace

AngleReport eval_angles(const DaemonConfig& config, const io::MarkerTrial& trial,
                        const io::OpenSimTable& reference, const std::string& reference_file,
                        const AngleOptions& options) {
  const Model& model = *config.tracker.model;
  if (model.coordinates.empty())
    throw std::invalid_argument(
        "angles: the model has no named coordinates. Fix: use a template or model with "
        "\"coordinates\" (e.g. config/templates/gait2354.json)");
  if (reference.cell_width != 1)
    throw std::invalid_argument("angles: " + reference_file +
                                " holds vectors in its cells, not coordinates. Fix: give a "
                                "Coordinates table (.mot)");
  const TrialSolution s = solve_trial(config, trial);
  AngleReport r;
  r.reference_file = reference_file;
  const std::size_t frames = trial.frames();
  for (std::size_t f = 0; f < frames; ++f) {
    r.residual_rms_mean_m += s.rms_m[f] / static_cast<double>(frames);
    if (s.max_m[f] > r.residual_max_m || f == 0) {
      r.residual_max_m = s.max_m[f];
      r.residual_max_frame = trial.clock().number(f);
      r.residual_max_marker = s.worst[f] >= 0 ? s.markers.labels[s.worst[f]] : "";
    }
  }

  // Reference rows matched to trial frames on time.
  const double tolerance_s =
      options.time_tolerance_s > 0.0 ? options.time_tolerance_s : 0.25 / trial.rate_hz;
  std::vector<std::size_t> rows;
  for (std::size_t row = 0; row < reference.rows; ++row) {
    const double t = reference.time_s[row];
    const double index = std::round((t - trial.file_time_s(0)) * trial.rate_hz);
    if (index < 0.0 || index >= static_cast<double>(frames)) continue;
    const auto f = static_cast<std::size_t>(index);
    if (std::abs(trial.file_time_s(f) - t) > tolerance_s) continue;
    if (f < s.first_measured || f >= s.end_measured) continue;  // no pose: no comparison
    rows.push_back(row);
    r.frames.push_back(f);
    r.frame_numbers.push_back(trial.clock().number(f));
    r.time_s.push_back(t);
  }
  if (rows.empty())
    throw std::invalid_argument(
        "angles: no row of " + reference_file + " matches a frame of the trial in time (" +
        std::to_string(reference.rows) + " rows; trial " +
        std::to_string(trial.file_time_s(0)) + "-" +
        std::to_string(trial.file_time_s(frames ? frames - 1 : 0)) +
        " s). Fix: compare a reference made from this trial");

  const double reference_rad = reference.in_degrees() ? std::numbers::pi / 180.0 : 1.0;
  const std::size_t n = model.coordinates.size();
  for (std::size_t c = 0; c < n; ++c) {
    const Coordinate& coord = model.coordinates[c];
    const int column = reference.find(coord.name);
    if (column <= 0) {  // absent (0 is the time column)
      r.not_in_reference.push_back(coord.name);
      continue;
    }
    CoordinateComparison cmp;
    cmp.name = coord.name;
    cmp.kind = coord.kind;
    const double scale = coord.kind == CoordinateKind::rotation ? reference_rad : 1.0;
    for (std::size_t k = 0; k < rows.size(); ++k) {
      cmp.fabrik_si.push_back(s.coordinates[r.frames[k] * n + c]);
      cmp.reference_si.push_back(reference.at(rows[k], static_cast<std::size_t>(column)) * scale);
    }
    compare(cmp);
    r.rows.push_back(std::move(cmp));
  }
  for (std::size_t c = 1; c < reference.columns.size(); ++c)
    if (model.find_coordinate(reference.columns[c]) < 0)
      r.not_in_model.push_back(reference.columns[c]);
  return r;
}

}  // namespace fabrik::eval
