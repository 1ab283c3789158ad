#include "markerless.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "calib/keypoint_calibration.hpp"
#include "common/quantile.hpp"
#include "config/daemon_config.hpp"
#include "distance_stats.hpp"
#include "io/opensim_table.hpp"
#include "offline/solve_trial.hpp"
#include "offline/prefilter.hpp"
#include "solver/units.hpp"
#include "tools/synth.hpp"

namespace fabrik::eval {

namespace {


DaemonConfig load_json_config(const nlohmann::ordered_json& j, const std::string& name) {
  return load_daemon_config(j.dump(), name);
}

KeypointCorruption case_corruption(const std::string& name, const KeypointCorruption& c,
                                   unsigned seed) {
  KeypointCorruption k = c;
  k.seed = seed;
  const bool all = name == "all";
  if (!all && name != "clean" && name != "jitter" && name != "dropouts" && name != "swaps")
    throw std::invalid_argument("unknown case '" + name +
                                "': use clean, jitter, dropouts, swaps or all");
  if (!all && name != "jitter") k.jitter_mm = 0.0;
  if (!all && name != "dropouts") k.dropouts_per_s = 0.0;
  if (!all && name != "swaps") k.swaps_per_s = 0.0;
  return k;
}

double wrap_deg(double d) {
  return std::remainder(d, 360.0);
}

// The one case of --trial: its corruption is in the file (unknown jitter; its listed runs).
constexpr const char* kFileCase = "file";

MarkerlessRow evaluate(const std::string& name, const KeypointCorruption& corruption,
                       const calib::CalibTemplate& tmpl, const tools::KeypointTrial& trial,
                       const MarkerlessOptions& o) {
  MarkerlessRow row;
  row.name = name;
  row.corruption = corruption;
  row.frames = trial.keypoints.frames();
  row.rate_hz = trial.keypoints.rate_hz;

  // Frames inside a swap, and the few after it, where a tracker recovers.
  std::vector<std::uint8_t> near_swap(row.frames, 0);
  for (const InjectedRun& r : trial.injected) {
    if (r.kind == InjectedRun::Kind::dropout) {
      ++row.dropouts;
      continue;
    }
    ++row.swaps;
    for (int f = r.first_frame; f < std::min<int>(r.first_frame + r.frames + 5, static_cast<int>(row.frames)); ++f)
      near_swap[static_cast<std::size_t>(f)] = 1;
  }
  for (std::uint8_t s : near_swap) row.swapped_frames += s;

  // Calibrate from the trial itself, as a user would from a markerless recording.
  const calib::KeypointCalibration cal =
      calib::calibrate_keypoints(tmpl, trial.keypoints, "<synthetic " + name + ">");
  DistanceStats len;
  for (const calib::KeypointLength& l : cal.lengths) {
    const int p = tmpl.find_point(l.point);
    const double err = std::abs(l.median_m - tmpl.points[static_cast<std::size_t>(p)].rest_m.norm());
    len.add(err, l.point);
    row.wide_lengths += l.wide;
  }
  row.length_error_rms_m = len.rms();
  row.length_error_max_m = len.max;
  row.length_error_worst = len.max_name;

  nlohmann::json cfg = nlohmann::json::parse(cal.result.config.dump());
  cfg.merge_patch(o.config_overrides);
  const DaemonConfig config = load_daemon_config(cfg.dump(), "<calibrated + overrides>");
  io::MarkerTrial keypoints = trial.keypoints;
  if (o.path == "offline") drop_left_out_then_filter(config, keypoints, o.filter_hz);
  // Live: frame by frame, as fabrikd would publish; offline: as fabrik solve (the joints
  // solved again on the gap-filled keypoints).
  const TrialSolution s = solve_trial(config, keypoints, {}, nullptr, {},
                                      o.path == "offline" ? TrialPass::offline : TrialPass::live);

  // Joint centres by name.
  DistanceStats all, swapped, clean;
  std::vector<double> errors;
  for (std::size_t j = 0; j < s.joints.labels.size(); ++j) {
    const int tj = trial.truth.joints.find(s.joints.labels[j]);
    if (tj < 0) continue;
    for (std::size_t f = 0; f < row.frames; ++f) {
      const Eigen::Vector3d est = s.joints.at(f, j);
      if (!est.allFinite()) continue;
      const double e = (est - trial.truth.joints.at(f, static_cast<std::size_t>(tj))).norm();
      all.add(e, s.joints.labels[j]);
      (near_swap[f] ? swapped : clean).add(e);
      errors.push_back(e);
    }
  }
  row.joint_rms_m = all.rms();
  row.joint_max_m = all.max;
  row.joint_max_name = all.max_name;
  row.joint_p95_m = quantile(errors, 0.95);
  row.joint_rms_swapped_m = swapped.rms();
  row.joint_rms_clean_m = clean.rms();

  // Rotational coordinates by name, and the lag that best aligns them with the truth.
  const std::size_t ne = s.coordinate_names.size(), nt = trial.truth.coordinate_names.size();
  std::vector<std::pair<std::size_t, std::size_t>> matched;  // (estimate, truth) columns
  for (std::size_t c = 0; c < ne; ++c) {
    if (!s.coordinate_is_rotation[c]) continue;
    for (std::size_t t = 0; t < nt; ++t)
      if (trial.truth.coordinate_names[t] == s.coordinate_names[c]) matched.emplace_back(c, t);
  }
  // The values as written, less the whole turns between the two series at their first
  // frame: a labelling matter there, but an estimate that later walks off by whole turns is
  // wrong in its file and counts (wrapping each frame's difference hid it).
  std::vector<double> turns_deg(ne, 0.0);
  for (const auto& [c, t] : matched)
    for (std::size_t f = 0; f < row.frames; ++f) {
      const double d_deg =
          (s.coordinates[f * ne + c] - trial.truth.coordinates[f * nt + t]) * kDegPerRad;
      if (std::isfinite(d_deg)) {
        turns_deg[c] = d_deg - wrap_deg(d_deg);
        break;
      }
    }
  const auto diff_deg = [&](std::size_t f_est, std::size_t f_truth, std::size_t c, std::size_t t) {
    return (s.coordinates[f_est * ne + c] - trial.truth.coordinates[f_truth * nt + t]) *
               kDegPerRad -
           turns_deg[c];
  };
  double sum_rms = 0.0;
  for (const auto& [c, t] : matched) {
    DistanceStats d;
    for (std::size_t f = 0; f < row.frames; ++f)
      if (std::isfinite(s.coordinates[f * ne + c])) d.add(std::abs(diff_deg(f, f, c, t)));
    row.angles.push_back({s.coordinate_names[c], d.rms(), d.max});
    sum_rms += d.rms();
  }
  row.angle_rms_mean_deg = matched.empty() ? 0.0 : sum_rms / static_cast<double>(matched.size());
  double best = -1.0;
  for (int lag = 0; lag <= 10; ++lag) {
    double sq = 0.0;
    for (const auto& [c, t] : matched)
      for (std::size_t f = static_cast<std::size_t>(lag); f < row.frames; ++f)
        if (std::isfinite(s.coordinates[f * ne + c])) {
          const double d = diff_deg(f, f - static_cast<std::size_t>(lag), c, t);
          sq += d * d;
        }
    if (best < 0.0 || sq < best) {
      best = sq;
      row.lag_frames = lag;
    }
  }
  return row;
}

// A trial written by `fabrik synth --keypoints`: FILE.trc, FILE.joints.trc, FILE.truth.mot
// and FILE.injected.csv beside it.
tools::KeypointTrial read_keypoint_trial(const std::string& path) {
  tools::KeypointTrial t;
  t.keypoints = io::read_trial(path);
  const std::string joints = tools::joints_sidecar_path(path);
  const std::string stem = tools::sidecar_stem(path);
  t.truth.joints = io::read_trial(joints);
  if (t.truth.joints.frames() != t.keypoints.frames())
    throw std::runtime_error(joints + ": " + std::to_string(t.truth.joints.frames()) +
                             " frames, the keypoints have " +
                             std::to_string(t.keypoints.frames()) +
                             ". Fix: use the files fabrik synth --keypoints wrote together");
  const io::OpenSimTable mot = io::read_opensim_table(stem + ".truth.mot");
  if (mot.rows != t.keypoints.frames())
    throw std::runtime_error(stem + ".truth.mot: " + std::to_string(mot.rows) +
                             " rows for " + std::to_string(t.keypoints.frames()) + " frames");
  // Only rotations are compared (by name), so every column is read as degrees.
  for (std::size_t c = 1; c < mot.columns.size(); ++c)
    t.truth.coordinate_names.push_back(mot.columns[c]);
  for (std::size_t r = 0; r < mot.rows; ++r)
    for (std::size_t c = 1; c < mot.columns.size(); ++c)
      t.truth.coordinates.push_back(mot.at(r, c) / kDegPerRad);
  std::ifstream csv(stem + ".injected.csv");
  std::string line, last_key;
  long long last_frame = -2;
  std::getline(csv, line);  // header
  while (std::getline(csv, line)) {
    std::stringstream fields(line);
    std::string frame, time, kind, names;
    std::getline(fields, frame, ',');
    std::getline(fields, time, ',');
    std::getline(fields, kind, ',');
    std::getline(fields, names);
    const long long f = std::stoll(frame) - t.keypoints.first_frame;
    if (kind + names != last_key || f != last_frame + 1) {
      InjectedRun run;
      run.kind = kind == "dropout"     ? InjectedRun::Kind::dropout
                 : kind == "swap_pair" ? InjectedRun::Kind::swap_pair
                                       : InjectedRun::Kind::swap_limb;
      run.first_frame = static_cast<int>(f);
      t.injected.push_back(run);
    }
    ++t.injected.back().frames;
    last_key = kind + names;
    last_frame = f;
  }
  return t;
}

}  // namespace

std::vector<MarkerlessRow> eval_markerless(const MarkerlessOptions& o) {
  const calib::CalibTemplate tmpl = calib::load_template_file(o.template_path);
  const calib::KeypointCalibration truth_cal = calib::nominal_keypoint_model(tmpl);
  const DaemonConfig truth_config = load_json_config(truth_cal.result.config, "<truth>");
  const tools::SynthSetup setup = tools::synth_setup(truth_config);
  tools::SynthOptions so;
  so.seconds = o.seconds;
  so.rate_hz = o.rate_hz;
  so.seed = o.seed;

  std::vector<MarkerlessRow> rows;
  if (!o.trial_path.empty()) {
    rows.push_back(
        evaluate(kFileCase, KeypointCorruption{}, tmpl, read_keypoint_trial(o.trial_path), o));
    return rows;
  }
  for (const std::string& name : o.cases) {
    const KeypointCorruption c = case_corruption(name, o.corruption, o.seed);
    rows.push_back(evaluate(name, c, tmpl, tools::make_keypoint_trial(setup, so, c), o));
  }
  return rows;
}

namespace {
std::string format_hz(double hz) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", hz);
  return text;
}
}  // namespace

std::string markerless_table(const std::vector<MarkerlessRow>& rows, const MarkerlessOptions& o) {
  std::ostringstream out;
  char line[512];
  const std::string path_text =
      o.path + (o.path == "offline"
                    ? " (zero-lag low-pass at " + format_hz(o.filter_hz) + " Hz before tracking)"
                    : std::string());
  if (!o.trial_path.empty()) {
    // A file's corruption is what synth wrote into it (its .injected.csv), not these options'.
    const MarkerlessRow* r = rows.empty() ? nullptr : &rows.front();
    std::snprintf(line, sizeof line,
                  "markerless trial: %s (%zu frames at %s Hz, %d dropouts and %d swaps listed "
                  "beside it); %s at nominal lengths; path %s\n\n",
                  o.trial_path.c_str(), r ? r->frames : std::size_t{0},
                  format_hz(r ? r->rate_hz : 0.0).c_str(), r ? r->dropouts : 0, r ? r->swaps : 0,
                  o.template_path.c_str(), path_text.c_str());
    out << line;
  } else {
    std::snprintf(line, sizeof line,
                  "markerless trial: %s at nominal lengths, %.0f s at %.0f Hz, seed %u; path %s\n"
                  "jitter %.1f mm per axis; dropouts %.2f/s of 2-%d frames; swaps %.2f/s of 2-%d "
                  "frames (%.0f %% whole limbs)\n\n",
                  o.template_path.c_str(), o.seconds, o.rate_hz, o.seed, path_text.c_str(),
                  o.corruption.jitter_mm, o.corruption.dropouts_per_s,
                  o.corruption.dropout_frames_max, o.corruption.swaps_per_s,
                  o.corruption.swap_frames_max, o.corruption.limb_swap_share * 100.0);
    out << line;
  }
  out << "case       drops swaps | length err mm   wide | joint centres mm: RMS    p95    max"
         "  (worst)          | near swaps  elsewhere | angles RMS deg: mean  lag frames\n";
  for (const MarkerlessRow& r : rows) {
    std::snprintf(line, sizeof line,
                  "%-10s %5d %5d | %5.1f %5.1f max %4d | %22.1f %6.1f %6.1f  (%-14s) | %10.1f %10.1f "
                  "| %20.2f %10d\n",
                  r.name.c_str(), r.dropouts, r.swaps, r.length_error_rms_m * 1e3,
                  r.length_error_max_m * 1e3, r.wide_lengths, r.joint_rms_m * 1e3,
                  r.joint_p95_m * 1e3, r.joint_max_m * 1e3, r.joint_max_name.c_str(),
                  r.joint_rms_swapped_m * 1e3, r.joint_rms_clean_m * 1e3, r.angle_rms_mean_deg,
                  r.lag_frames);
    out << line;
  }
  out << "\nPer coordinate, RMS deg (columns: cases)\n";
  if (rows.empty()) return out.str();
  std::snprintf(line, sizeof line, "  %-18s", "coordinate");
  out << line;
  for (const MarkerlessRow& r : rows) {
    std::snprintf(line, sizeof line, " %9s", r.name.c_str());
    out << line;
  }
  out << "\n";
  for (std::size_t c = 0; c < rows[0].angles.size(); ++c) {
    std::snprintf(line, sizeof line, "  %-18s", rows[0].angles[c].name.c_str());
    out << line;
    for (const MarkerlessRow& r : rows) {
      std::snprintf(line, sizeof line, " %9.2f", c < r.angles.size() ? r.angles[c].rms_deg : NAN);
      out << line;
    }
    out << "\n";
  }
  return out.str();
}

nlohmann::json markerless_json(const std::vector<MarkerlessRow>& rows) {
  nlohmann::json j = nlohmann::json::array();
  for (const MarkerlessRow& r : rows) {
    nlohmann::json angles = nlohmann::json::object();
    for (const CoordinateError& a : r.angles)
      angles[a.name] = {{"rms_deg", a.rms_deg}, {"max_deg", a.max_deg}};
    j.push_back({{"case", r.name},
                 {"jitter_mm",
                  r.name == kFileCase ? nlohmann::json() : nlohmann::json(r.corruption.jitter_mm)},
                 {"dropouts", r.dropouts},
                 {"swaps", r.swaps},
                 {"swapped_frames", r.swapped_frames},
                 {"frames", r.frames},
                 {"length_error_rms_mm", r.length_error_rms_m * 1e3},
                 {"length_error_max_mm", r.length_error_max_m * 1e3},
                 {"length_error_worst", r.length_error_worst},
                 {"wide_lengths", r.wide_lengths},
                 {"joint_rms_mm", r.joint_rms_m * 1e3},
                 {"joint_p95_mm", r.joint_p95_m * 1e3},
                 {"joint_max_mm", r.joint_max_m * 1e3},
                 {"joint_max_name", r.joint_max_name},
                 {"joint_rms_near_swaps_mm", r.joint_rms_swapped_m * 1e3},
                 {"joint_rms_elsewhere_mm", r.joint_rms_clean_m * 1e3},
                 {"angle_rms_mean_deg", r.angle_rms_mean_deg},
                 {"lag_frames", r.lag_frames},
                 {"angles", angles}});
  }
  return j;
}

}  // namespace fabrik::eval
