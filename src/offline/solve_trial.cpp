#include "solve_trial.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>

#include "common/ascii_case.hpp"
#include "common/device_path.hpp"
#include "common/quantile.hpp"
#include "io/output_file.hpp"
#include "solver/units.hpp"
#include "tracking/tracker.hpp"
#include "tracking/two_sided_fill.hpp"

namespace fabrik {

TrialSolution solve_trial(const DaemonConfig& config, const io::MarkerTrial& trial,
                          const std::function<void(std::size_t, std::size_t)>& progress,
                          const io::OrientationTable* orientations,
                          const TrackedFrameHook& on_frame, TrialPass pass) {
  Tracker tracker(config.tracker);
  const Model& model = tracker.model();
  const int n = tracker.marker_count();
  TrialSolution s;
  std::vector<int> column(n, -1);  // trial column of each tracked marker
  for (int i = 0; i < n; ++i) {
    column[i] = trial.find(config.tracker.markers[i].marker);
    if (column[i] < 0) s.missing_in_trial.push_back(config.tracker.markers[i].marker);
  }
  for (const std::string& label : trial.labels) {
    const bool tracked = std::any_of(config.tracker.markers.begin(), config.tracker.markers.end(),
                                     [&](const MarkerTarget& m) { return m.marker == label; });
    if (!tracked) s.ignored_in_trial.push_back(label);
  }
  // Orientation columns of the config's sensors (-1: not in the table).
  const std::vector<SensorTarget>& sensors = config.tracker.sensors.sensors;
  const int sensor_count = static_cast<int>(sensors.size());
  std::vector<int> sensor_column(sensor_count, -1);
  if (orientations) {
    for (int k = 0; k < sensor_count; ++k) {
      sensor_column[k] = orientations->find(sensors[k].sensor);
      if (sensor_column[k] < 0) s.sensors_missing_in_table.push_back(sensors[k].sensor);
    }
    for (const std::string& name : orientations->sensors)
      if (std::none_of(sensors.begin(), sensors.end(),
                       [&](const SensorTarget& t) { return t.sensor == name; }))
        s.ignored_in_table.push_back(name);
  }
  // Without markers the table's rows are the frames.
  const bool table_frames = orientations && trial.labels.empty();
  const std::size_t frames = table_frames ? orientations->rows() : trial.frames();
  for (auto* out : {&s.joints, &s.markers, &s.model_markers}) {
    out->rate_hz = table_frames ? orientations->rate_hz : trial.rate_hz;
    out->first_frame =
        table_frames ? 1 + static_cast<int>(std::lround(orientations->time_s.front() *
                                                        orientations->rate_hz))
                     : trial.first_frame;
    out->first_time_frames = table_frames ? orientations->time_s.front() * orientations->rate_hz
                                          : trial.first_time_frames;
  }
  std::vector<Eigen::Quaterniond> q_table(orientations ? orientations->sensors.size() : 0);
  std::vector<Eigen::Quaterniond> q_sensor(sensor_count, Eigen::Quaterniond::Identity());
  std::vector<std::uint8_t> sensor_visible(sensor_count, 0);
  std::vector<std::uint8_t> sensor_ever_measured(sensor_count, 0);
  for (const Joint& j : model.joints) s.joints.labels.push_back(j.name);
  for (const MarkerTarget& m : config.tracker.markers) s.markers.labels.push_back(m.marker);
  s.model_markers.labels = s.markers.labels;
  s.joints.positions_m.reserve(frames * s.joints.labels.size());
  s.model_markers.positions_m.reserve(frames * n);
  for (const Coordinate& c : model.coordinates) {
    s.coordinate_names.push_back(c.name);
    s.coordinate_is_rotation.push_back(c.kind == CoordinateKind::rotation ? 1 : 0);
  }
  s.coordinates.reserve(frames * s.coordinate_names.size());

  std::vector<Eigen::Vector3d> measured(n);
  std::vector<std::uint8_t> visible(n);
  std::vector<std::size_t> missing_frames(n, 0);
  const auto time_of = [&](std::size_t f) {
    return table_frames ? orientations->time_s[f] - orientations->time_s.front() : trial.time_s(f);
  };
  // The sensors' inputs of frame f (a missing one keeps its last orientation, unused).
  const auto sample_sensors = [&](std::size_t f) {
    if (!orientations) return;
    if (table_frames) {
      for (std::size_t k = 0; k < q_table.size(); ++k) q_table[k] = orientations->at(f, k);
    } else {
      orientations->sample(trial.file_time_s(f), q_table);
    }
    for (int k = 0; k < sensor_count; ++k) {
      const int c = sensor_column[k];
      sensor_visible[k] = c >= 0 && q_table[c].coeffs().allFinite() ? 1 : 0;
      if (sensor_visible[k]) q_sensor[k] = q_table[c], sensor_ever_measured[k] = 1;
    }
  };
  for (std::size_t f = 0; f < frames; ++f) {
    int seen = 0;
    for (int i = 0; i < n; ++i) {
      measured[i] = column[i] >= 0 && !table_frames ? trial.at(f, column[i])
                                                    : Eigen::Vector3d::Constant(NAN);
      visible[i] = measured[i].allFinite() ? 1 : 0;
      seen += visible[i];
      if (column[i] >= 0 && !visible[i]) ++missing_frames[i];
    }
    s.measured.push_back(seen);
    const double time_s = time_of(f);
    sample_sensors(f);
    const TrackResult& r = tracker.track(time_s, measured, visible, q_sensor, sensor_visible);
    if (on_frame) on_frame(f, time_s, tracker, r);
    s.sensor_rms_rad.push_back(r.sensor_occluded_count < sensor_count ? r.sensor_rms_rad : NAN);
    s.sensors_measured.push_back(sensor_count - r.sensor_occluded_count);
    s.joints.positions_m.insert(s.joints.positions_m.end(), r.joints_world_m.begin(),
                                r.joints_world_m.end());
    s.model_markers.positions_m.insert(s.model_markers.positions_m.end(), r.markers_world_m.begin(),
                                       r.markers_world_m.end());
    s.outlier.insert(s.outlier.end(), r.outliers.begin(), r.outliers.end());
    s.outlier_count.push_back(r.outlier_count);
    s.quality.push_back(r.quality);
    s.rms_m.push_back(r.residual_rms_m);
    s.max_m.push_back(r.residual_max_m);
    s.worst.push_back(r.worst_marker);
    s.solve_us.push_back(r.solve_us);
    s.iterations.push_back(r.solve.iterations);
    s.status.emplace_back(to_string(r.solve.status));
    s.coordinates.insert(s.coordinates.end(), r.coordinates.begin(), r.coordinates.end());
    if (progress && (f % 64 == 0 || f + 1 == frames)) progress(f + 1, frames);
  }
  // Offline both sides of every gap are known: the markers are the measured samples with
  // their gaps filled from both sides (the joint centres are solved on them below). Not
  // the model's markers where measured: the fill meets the measurement at a gap's edges, and
  // the fitted markers beside it would step by the fit's misfit there.
  std::vector<double> times_s(frames);
  std::vector<Eigen::Vector3d> all_m(frames * n);
  std::vector<std::uint8_t> all_visible(frames * n);
  for (std::size_t f = 0; f < frames; ++f) {
    times_s[f] = trial.time_s(f);
    for (int i = 0; i < n; ++i) {
      const std::size_t k = f * n + i;
      all_m[k] = column[i] >= 0 ? trial.at(f, column[i]) : Eigen::Vector3d::Constant(NAN);
      all_visible[k] = all_m[k].allFinite() ? 1 : 0;
    }
  }
  TwoSidedFill fill = fill_two_sided(config.tracker, times_s, all_m, all_visible);
  s.markers.positions_m = std::move(fill.markers_m);
  for (const FilledGap& g : fill.gaps)
    s.filled.push_back({config.tracker.markers[g.marker].marker, g.first, g.end, to_string(g.method)});
  for (int i = 0; i < n; ++i) {
    if (column[i] < 0 || frames == 0 || 2 * missing_frames[i] <= frames) continue;
    const std::vector<std::size_t>& zeros = trial.source.zero_samples;
    const auto c = static_cast<std::size_t>(column[i]);
    s.mostly_missing.push_back(
        {config.tracker.markers[i].marker, missing_frames[i], c < zeros.size() ? zeros[c] : 0});
    if (missing_frames[i] == frames) s.missing_in_trial.push_back(config.tracker.markers[i].marker);
  }
  // Offline the joint centres and coordinates come from a second pass over the markers with
  // their gaps filled: the causal pass holds or predicts a segment through a gap, and its
  // pose lags for a few frames after the markers return (the hand-over); the filled markers
  // know both sides. The residual, outlier and quality figures stay those of the causal pass
  // against the measurements, and the model markers what fabrikd publishes live.
  if (pass == TrialPass::offline && !fill.gaps.empty()) {
    Tracker again(config.tracker);
    std::fill(sensor_ever_measured.begin(), sensor_ever_measured.end(), 0);
    s.joints.positions_m.clear();
    s.coordinates.clear();
    for (std::size_t f = 0; f < frames; ++f) {
      for (int i = 0; i < n; ++i) {
        measured[i] = s.markers.positions_m[f * n + i];
        visible[i] = measured[i].allFinite() ? 1 : 0;
      }
      sample_sensors(f);
      const TrackResult& r = again.track(time_of(f), measured, visible, q_sensor, sensor_visible);
      s.joints.positions_m.insert(s.joints.positions_m.end(), r.joints_world_m.begin(),
                                  r.joints_world_m.end());
      s.coordinates.insert(s.coordinates.end(), r.coordinates.begin(), r.coordinates.end());
    }
    s.solved_on_filled_markers = true;
  }
  // Before the first frame with a measurement the tracker holds its rest posture, after the
  // last the last pose for as long as the trial's empty tail: no pose of the subject, so the
  // joint centres, model markers and coordinates are missing there (a gap between measured
  // frames is solved on the fill across it; the live pass holds the pose before it).
  const auto any_measured = [&](std::size_t f) {
    return s.measured[f] > 0 || s.sensors_measured[f] > 0;
  };
  while (s.first_measured < frames && !any_measured(s.first_measured)) ++s.first_measured;
  s.end_measured = frames;
  while (s.end_measured > s.first_measured && !any_measured(s.end_measured - 1)) --s.end_measured;
  const std::size_t joints = s.joints.labels.size(), coords = s.coordinate_names.size();
  for (std::size_t f = 0; f < frames; ++f) {
    if (f == s.first_measured) f = std::max(f, s.end_measured);
    if (f >= frames) break;
    std::fill_n(s.joints.positions_m.begin() + static_cast<std::ptrdiff_t>(f * joints), joints,
                Eigen::Vector3d::Constant(NAN));
    std::fill_n(s.model_markers.positions_m.begin() + static_cast<std::ptrdiff_t>(f * n), n,
                Eigen::Vector3d::Constant(NAN));
    std::fill_n(s.coordinates.begin() + static_cast<std::ptrdiff_t>(f * coords), coords, NAN);
  }
  // As for markers: a sensor whose column has no usable cell at any frame is missing too.
  for (int k = 0; k < sensor_count; ++k)
    if (orientations && sensor_column[k] >= 0 && frames > 0 && !sensor_ever_measured[k])
      s.sensors_missing_in_table.push_back(sensors[k].sensor);
  return s;
}

nlohmann::json solution_summary(const TrialSolution& s) {
  const std::size_t frames = s.rms_m.size();
  double rms_sum = 0.0, rms_max = 0.0, max_m = 0.0;
  std::size_t max_frame = 0, with_markers = 0, outlier_samples = 0, outlier_frames = 0;
  std::size_t measured_samples = 0;
  std::map<std::string, int> worst_count, status_count, quality_count, outlier_markers;
  // Every verdict is reported, a zero too: a script reads report["quality"]["poor"].
  for (FitQuality q : {FitQuality::good, FitQuality::poor, FitQuality::none})
    quality_count[std::string(to_string(q))] = 0;
  for (std::size_t f = 0; f < frames; ++f) {
    ++status_count[s.status[f]];
    if (f < s.quality.size()) ++quality_count[std::string(to_string(s.quality[f]))];
    if (f < s.outlier_count.size()) {
      outlier_samples += static_cast<std::size_t>(s.outlier_count[f]);
      outlier_frames += s.outlier_count[f] > 0 ? 1 : 0;
      const std::size_t n = s.markers.labels.size();
      for (std::size_t i = 0; i < n; ++i)
        if (s.outlier[f * n + i]) ++outlier_markers[s.markers.labels[i]];
    }
    if (f < s.measured.size()) measured_samples += static_cast<std::size_t>(s.measured[f]);
    if (f < s.measured.size() && s.measured[f] == 0) continue;  // no residual to speak of
    ++with_markers;
    rms_sum += s.rms_m[f];
    rms_max = std::max(rms_max, s.rms_m[f]);
    if (s.max_m[f] > max_m) max_m = s.max_m[f], max_frame = f;
    if (s.worst[f] >= 0) ++worst_count[s.markers.labels[s.worst[f]]];
  }
  std::string worst_name;
  if (frames > 0 && s.worst[max_frame] >= 0) worst_name = s.markers.labels[s.worst[max_frame]];
  std::string most_often;
  int most = 0;
  for (const auto& [name, count] : worst_count)
    if (count > most) most = count, most_often = name;
  std::vector<double> iterations(s.iterations.begin(), s.iterations.end());
  double it_sum = 0;
  for (double i : iterations) it_sum += i;
  nlohmann::json mostly_missing = nlohmann::json::array();
  for (const MostlyMissing& m : s.mostly_missing) {
    mostly_missing.push_back({{"marker", m.marker},
                              {"missing_frames", m.missing_frames},
                              {"zero_frames", m.zero_frames}});
  }
  // Per marker, the filled runs as [first, last] frame numbers of the file.
  // filled_method: per marker, how each of those runs was filled.
  nlohmann::json filled = nlohmann::json::object(), filled_method = nlohmann::json::object();
  for (const FilledRun& r : s.filled) {
    filled[r.marker].push_back({s.markers.first_frame + static_cast<long long>(r.first),
                                s.markers.first_frame + static_cast<long long>(r.end) - 1});
    filled_method[r.marker].push_back(r.method);
  }
  double sensor_sum = 0.0, sensor_max = 0.0;
  std::size_t with_sensors = 0;
  for (double e : s.sensor_rms_rad)
    if (std::isfinite(e)) sensor_sum += e, sensor_max = std::max(sensor_max, e), ++with_sensors;
  nlohmann::json summary = {
      {"frames", frames},
      {"frames_without_markers", frames - with_markers},
      {"frames_before_first_measurement", s.first_measured},
      {"frames_after_last_measurement", frames - s.end_measured},
      {"solved_on_filled_markers", s.solved_on_filled_markers},
      {"residual_mm",
       {{"rms_mean", with_markers ? rms_sum / static_cast<double>(with_markers) * 1e3 : 0.0},
        {"rms_max", rms_max * 1e3},
        {"max", max_m * 1e3},
        {"max_frame", s.markers.first_frame + static_cast<long long>(max_frame)},
        {"max_marker", worst_name},
        {"worst_marker_most_often", most_often}}},
      {"solve_us",
       {{"p50", quantile(s.solve_us, 0.5)},
        {"p99", quantile(s.solve_us, 0.99)},
        {"max", quantile(s.solve_us, 1.0)}}},
      {"iterations_mean", frames ? it_sum / static_cast<double>(frames) : 0.0},
      {"status", status_count},
      {"quality", quality_count},
      {"outliers",
       {{"samples", outlier_samples},
        {"frames", outlier_frames},
        {"percent_of_measured", measured_samples ? 100.0 * static_cast<double>(outlier_samples) /
                                                       static_cast<double>(measured_samples)
                                                 : 0.0},
        {"markers", outlier_markers}}},
      {"markers_missing_in_trial", s.missing_in_trial},
      {"filled", filled},
      {"filled_method", filled_method},
      {"markers_mostly_missing", mostly_missing},
      {"trial_labels_not_tracked", s.ignored_in_trial}};
  if (!s.sensor_rms_rad.empty() && with_sensors + s.sensors_missing_in_table.size() +
                                           s.ignored_in_table.size() > 0) {
    summary["orientations"] = {
        {"frames_with_sensors", with_sensors},
        {"sensor_error_deg",
         {{"rms_mean", with_sensors ? sensor_sum / static_cast<double>(with_sensors) * kDegPerRad
                                    : 0.0},
          {"rms_max", sensor_max * kDegPerRad}}},
        {"sensors_missing_in_table", s.sensors_missing_in_table},
        {"table_columns_not_used", s.ignored_in_table}};
  }
  return summary;
}

io::OpenSimTable angles_table(const TrialSolution& s) {
  io::OpenSimTable t = io::coordinates_table(s.coordinate_names, true);
  const std::size_t n = s.coordinate_names.size();
  std::vector<double> row(n);
  // From the first frame with a measurement to the last: outside them there is no pose to
  // write (OpenSim's tools read a row of NaN as data).
  for (std::size_t f = s.first_measured; f < s.end_measured; ++f) {
    for (std::size_t c = 0; c < n; ++c)
      row[c] = s.coordinates[f * n + c] * (s.coordinate_is_rotation[c] ? kDegPerRad : 1.0);
    t.add_row(s.joints.file_time_s(f), row);
  }
  return t;
}

void write_filled_csv(const std::string& path, const TrialSolution& s, const io::MarkerTrial& trial) {
  std::ofstream out = io::open_output_file(path);
  out << "marker,first_frame,last_frame,first_time_s,last_time_s,samples,method\n";
  for (const FilledRun& r : s.filled)
    out << r.marker << ',' << trial.first_frame + static_cast<long long>(r.first) << ','
        << trial.first_frame + static_cast<long long>(r.end) - 1 << ','
        << trial.file_time_s(r.first) << ',' << trial.file_time_s(r.end - 1) << ','
        << r.end - r.first << ',' << r.method << '\n';
  io::finish_output_file(out, path);
}

std::size_t drop_implausible_samples(io::MarkerTrial& trial, double max_abs_coordinate_m) {
  std::size_t dropped = 0;
  for (Eigen::Vector3d& p_m : trial.positions_m)
    if (p_m.allFinite() && !(p_m.cwiseAbs().maxCoeff() <= max_abs_coordinate_m)) {
      p_m.setConstant(std::numeric_limits<double>::quiet_NaN());
      ++dropped;
    }
  return dropped;
}

void write_trial_file(const std::string& path, const io::MarkerTrial& trial) {
  if (has_suffix_ci(path, ".trc") || is_stream(path)) return io::write_trc(path, trial, "mm");
  if (!has_suffix_ci(path, ".csv"))
    throw io::FormatError(path, "unknown output format: use .trc or .csv");
  std::ofstream out = io::open_output_file(path);
  out << "frame,time_s";
  for (const std::string& l : trial.labels)
    out << ',' << l << "_x_mm," << l << "_y_mm," << l << "_z_mm";
  out << '\n';
  char buf[64];
  for (std::size_t f = 0; f < trial.frames(); ++f) {
    // The shortest exact form (as the TRC writer's): an ostream's 6 digits would repeat
    // times past 1000 s at 240 Hz.
    const auto t = std::to_chars(buf, buf + sizeof buf, trial.file_time_s(f));
    out << trial.first_frame + static_cast<int>(f) << ',' << std::string_view(buf, t.ptr);
    for (std::size_t m = 0; m < trial.markers(); ++m)
      for (int k = 0; k < 3; ++k) {
        const double v = trial.at(f, m)[k];
        if (std::isfinite(v)) {
          std::snprintf(buf, sizeof buf, ",%.4f", v * 1e3);
          out << buf;
        } else {
          out << ',';
        }
      }
    out << '\n';
  }
  io::finish_output_file(out, path);
}

}  // namespace fabrik
