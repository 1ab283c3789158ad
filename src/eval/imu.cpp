#include "imu.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "calib/calib_template.hpp"
#include "calib/calibrate.hpp"
#include "calib/sensor_calibration.hpp"
#include "config/model_loader.hpp"
#include "distance_stats.hpp"
#include "solver/units.hpp"
#include "synth/synthetic_motion.hpp"
#include "synth/synthetic_sensors.hpp"
#include "tracking/tracker.hpp"

namespace fabrik::eval {

namespace {

// A knee flexion above this starts a swing phase's peak search (well above
// stance flexion, ~15-25 deg, and below any swing peak worth the name).
constexpr double kSwingKneeDeg = 35.0;

constexpr double kImuTolerance_m = 1e-5;
constexpr int kImuMaxIterations = 200;

// One synthetic setup: which markers, which segments carry sensors.
struct Setup {
  const char* name;
  bool all_markers, pelvis_markers, sensors_on_root, sensors_on_limbs;
};

}  // namespace

std::vector<ImuSyntheticRow> eval_imu_synthetic(const DaemonConfig& config,
                                                const ImuSyntheticOptions& o) {
  const Model& model = *config.tracker.model;
  const Setup setups[] = {{"markers only", true, false, false, false},
                          {"IMUs only", false, false, true, true},
                          {"pelvis markers + IMUs", false, true, false, true}};
  const auto frames = static_cast<std::size_t>(o.seconds * o.rate_hz);
  const auto still = static_cast<std::size_t>(o.calibration_s * o.rate_hz);
  std::vector<ImuSyntheticRow> rows;
  for (const Setup& setup : setups) {
    TrackerSetup ts = config.tracker;
    // Chains turned by orientation targets converge more slowly than marker
    // clusters: a marker config's 0.1 mm stall rule stops them 1 deg short
    // (IMUs only, no noise: 1.13 deg RMS with default.json's stopping, 0.08
    // deg with these).
    ts.solver.tolerance_m = std::min(ts.solver.tolerance_m, kImuTolerance_m);
    ts.solver.stall_tolerance_m = std::min(ts.solver.stall_tolerance_m, kImuTolerance_m);
    ts.solver.max_iterations = std::max(ts.solver.max_iterations, kImuMaxIterations);
    ts.markers.clear();
    for (const MarkerTarget& m : config.tracker.markers)
      if (setup.all_markers || (setup.pelvis_markers && model.points[m.point].segment == 0))
        ts.markers.push_back(m);
    std::vector<int> segments;
    for (int s = 0; s < static_cast<int>(model.segments.size()); ++s)
      if (s == 0 ? setup.sensors_on_root : setup.sensors_on_limbs) segments.push_back(s);
    SyntheticSensors sim(segments, {o.sensor_noise_deg / kDegPerRad, o.drift_deg_per_s / kDegPerRad},
                         o.seed + 7);
    // Calibration: standing still in the rest posture; each sensor's readings
    // averaged. The heading is given (as a lab aligning the IMU world with its
    // mocap world would give it); the drift then moves it.
    if (!segments.empty()) {
      SensorSection spec;
      spec.calibration_pose = "rest";
      spec.world.rotation_xyz_rad = Eigen::Vector3d(-std::numbers::pi / 2, 0, 0);
      spec.world.heading_rad = sim.heading_rad();
      std::vector<std::string> names;
      for (int s : segments) {
        names.push_back(model.segments[s].name + "_imu");
        SensorEntry entry;
        entry.sensor = names.back();
        entry.segment = model.segments[s].name;
        spec.entries.push_back(entry);
      }
      const Posture rest = Posture::rest(model);
      std::vector<std::vector<Eigen::Quaterniond>> samples(segments.size());
      std::vector<Eigen::Quaterniond> q(segments.size()), mean(segments.size());
      for (std::size_t f = 0; f < still; ++f) {
        sim.sample(rest, static_cast<double>(f) / o.rate_hz, q);
        for (std::size_t k = 0; k < q.size(); ++k) samples[k].push_back(q[k]);
      }
      for (std::size_t k = 0; k < q.size(); ++k) mean[k] = calib::mean_rotation(samples[k], nullptr);
      const calib::SensorCalibration c = calib::calibrate_sensors(spec, model, rest, names, mean);
      ts.sensors = sensor_setup(c.section, model);
    }
    std::vector<int> points;
    for (const MarkerTarget& m : ts.markers) points.push_back(m.point);
    MotionSettings settings;
    settings.seed = o.seed;
    SyntheticMotion motion(model, settings);
    Tracker tracker(ts);
    Posture truth = Posture::rest(model);
    std::vector<Eigen::Vector3d> measured(points.size());
    const std::vector<std::uint8_t> visible(points.size(), 1);
    std::vector<Eigen::Quaterniond> q(segments.size());
    const std::vector<std::uint8_t> q_visible(segments.size(), 1);
    DistanceStats angles, centres;
    const bool root_held = ts.markers.empty();
    for (std::size_t f = 0; f < frames; ++f) {
      const double t = static_cast<double>(f) / o.rate_hz;
      motion.posture_at(t, truth);
      motion.sample(truth, points, o.marker_noise_mm * 1e-3, measured);
      sim.sample(truth, o.calibration_s + t, q);
      const TrackResult& r = tracker.track(t, measured, visible, q, q_visible);
      const Posture& p = tracker.posture();
      for (std::size_t s = 1; s < model.segments.size(); ++s) {
        const int parent = model.segments[s].parent;
        const Eigen::Quaterniond a = p.segments[parent].q_world.conjugate() * p.segments[s].q_world;
        const Eigen::Quaterniond b =
            truth.segments[parent].q_world.conjugate() * truth.segments[s].q_world;
        angles.add(a.angularDistance(b));
      }
      // Without markers nothing says where the body is: compare relative to the root.
      const Eigen::Vector3d shift_m =
          root_held ? Eigen::Vector3d(truth.segments[0].base_world_m - p.segments[0].base_world_m)
                    : Eigen::Vector3d::Zero();
      for (std::size_t j = 0; j < model.joints.size(); ++j)
        centres.add((r.joints_world_m[j] + shift_m -
                     truth.point_world_m(model, model.joints[j].point))
                        .norm());
    }
    ImuSyntheticRow row;
    row.setup = setup.name;
    row.markers = ts.markers.size();
    row.sensors = segments.size();
    row.frames = frames;
    row.joint_angle_rms_rad = angles.rms();
    row.joint_angle_max_rad = angles.max;
    row.joint_rms_m = centres.rms();
    row.joint_max_m = centres.max;
    rows.push_back(row);
  }
  return rows;
}

GaitReport gait_report(const TrialSolution& s) {
  GaitReport g;
  const std::size_t n = s.coordinate_names.size();
  g.frames = s.status.size();
  const auto column = [&](const std::string& name) -> int {
    const auto it = std::find(s.coordinate_names.begin(), s.coordinate_names.end(), name);
    return it == s.coordinate_names.end() ? -1 : static_cast<int>(it - s.coordinate_names.begin());
  };
  const auto value_deg = [&](std::size_t f, int c) { return s.coordinates[f * n + c] * kDegPerRad; };
  for (std::size_t f = 0; f < g.frames; ++f) {
    bool finite = true;
    for (std::size_t j = 0; j < s.joints.labels.size(); ++j)
      finite = finite && s.joints.at(f, j).allFinite();
    if (finite && s.status[f] != "no_targets" && s.status[f] != "size_mismatch") ++g.frames_tracked;
  }
  g.knee_flexion_min_deg = 1e9;
  g.hip_flexion_min_deg = 1e9;
  g.hip_flexion_max_deg = -1e9;
  for (const char side : {'r', 'l'}) {
    const int knee = column(std::string("knee_angle_") + side);
    const int hip = column(std::string("hip_flexion_") + side);
    if (knee < 0 || hip < 0) continue;
    for (std::size_t f = 0; f < g.frames;) {
      g.hip_flexion_min_deg = std::min(g.hip_flexion_min_deg, value_deg(f, hip));
      g.hip_flexion_max_deg = std::max(g.hip_flexion_max_deg, value_deg(f, hip));
      const double flexion = -value_deg(f, knee);
      g.knee_flexion_min_deg = std::min(g.knee_flexion_min_deg, flexion);
      if (!(flexion > kSwingKneeDeg)) {  // NaN too (no pose before the first measurement)
        ++f;
        continue;
      }
      GaitStride peak{side, 0.0, -1e9};
      for (; f < g.frames && -value_deg(f, knee) > kSwingKneeDeg; ++f) {
        g.hip_flexion_min_deg = std::min(g.hip_flexion_min_deg, value_deg(f, hip));
        g.hip_flexion_max_deg = std::max(g.hip_flexion_max_deg, value_deg(f, hip));
        if (-value_deg(f, knee) > peak.knee_flexion_deg)
          peak = {side, s.joints.file_time_s(f), -value_deg(f, knee)};
      }
      g.strides.push_back(peak);
    }
  }
  std::sort(g.strides.begin(), g.strides.end(),
            [](const GaitStride& a, const GaitStride& b) { return a.time_s < b.time_s; });
  g.alternating = g.strides.size() >= 2;
  for (std::size_t k = 1; k < g.strides.size(); ++k)
    g.alternating = g.alternating && g.strides[k].side != g.strides[k - 1].side;
  for (std::size_t c = 0; c < n; ++c) {
    if (!s.coordinate_is_rotation[c]) continue;
    for (std::size_t f = 1; f < g.frames; ++f) {
      // As written: the coordinates never wrap, so a turn between frames is a jump.
      const double d = value_deg(f, static_cast<int>(c)) - value_deg(f - 1, static_cast<int>(c));
      if (std::abs(d) > g.max_jump_deg) {
        g.max_jump_deg = std::abs(d);
        g.max_jump_coordinate = s.coordinate_names[c];
        g.max_jump_frame = s.joints.clock().number(f);
      }
    }
  }
  DistanceStats sensor;
  for (double e : s.sensor_rms_rad)
    if (std::isfinite(e)) sensor.add(e);
  g.sensor_error_rms_deg = sensor.rms() * kDegPerRad;
  return g;
}

OpenSenseRun eval_imu_opensense(const std::string& template_path, const std::string& static_path,
                                const std::string& placement_path, const std::string& walk_path) {
  const calib::CalibTemplate tmpl = calib::load_template_file(template_path);
  const io::MarkerTrial trial = io::read_trial(static_path);
  calib::CalibrationResult r = calib::calibrate(tmpl, trial, static_path);
  const Model model = load_model(nlohmann::json::parse(r.model.dump()), "<calibrated model>");
  calib::calibrate_sensors_into(tmpl.sensors, model, io::read_orientation_table(placement_path),
                                placement_path, r.config);
  OpenSenseRun run{load_daemon_config(r.config.dump(), "<calibrated from " + static_path + ">"),
                   {}, {}};
  const io::OrientationTable walk = io::read_orientation_table(walk_path);
  run.solution = solve_trial(run.config, io::MarkerTrial{}, {}, &walk);
  run.report = gait_report(run.solution);
  return run;
}

std::string imu_synthetic_table(const std::vector<ImuSyntheticRow>& rows,
                                const ImuSyntheticOptions& o) {
  char line[512];
  std::snprintf(line, sizeof line,
                "Synthetic truth: %g s at %g Hz; markers %g mm noise per axis; IMUs %g deg noise "
                "per axis, heading drift within +-%g deg/s, calibrated standing still for %g s; solver stops at 0.01 mm, 200 iterations\n",
                o.seconds, o.rate_hz, o.marker_noise_mm, o.sensor_noise_deg, o.drift_deg_per_s,
                o.calibration_s);
  std::string out = line;
  out += "  setup                    markers  IMUs  joint angle RMS / max deg   joint centre RMS / max mm\n";
  for (const ImuSyntheticRow& r : rows) {
    std::snprintf(line, sizeof line, "  %-24s %7zu %5zu  %10.2f / %-12.2f %12.2f / %.2f%s\n",
                  r.setup.c_str(), r.markers, r.sensors, r.joint_angle_rms_rad * kDegPerRad,
                  r.joint_angle_max_rad * kDegPerRad, r.joint_rms_m * 1e3, r.joint_max_m * 1e3,
                  r.markers == 0 ? " (relative to the root)" : "");
    out += line;
  }
  return out;
}

std::string gait_table(const GaitReport& g) {
  char line[256];
  std::string out;
  std::snprintf(line, sizeof line,
                "OpenSense walk, 8 IMUs alone: %zu frames, %zu tracked; sensor error RMS %.2f deg\n"
                "  knee flexion peaks in swing (%zu, L/R %s):",
                g.frames, g.frames_tracked, g.sensor_error_rms_deg, g.strides.size(),
                g.alternating ? "alternating" : "NOT alternating");
  out += line;
  for (const GaitStride& s : g.strides) {
    std::snprintf(line, sizeof line, " %c %.1f", s.side == 'r' ? 'R' : 'L', s.knee_flexion_deg);
    out += line;
  }
  double lo = 1e9, hi = -1e9;
  for (const GaitStride& s : g.strides)
    lo = std::min(lo, s.knee_flexion_deg), hi = std::max(hi, s.knee_flexion_deg);
  std::snprintf(line, sizeof line,
                "\n  knee flexion peaks %.1f .. %.1f deg; knee flexion never below %.1f deg\n"
                "  hip flexion %.1f .. %.1f deg\n"
                "  largest frame-to-frame change %.2f deg (%s, frame %lld)\n",
                lo, hi, g.knee_flexion_min_deg, g.hip_flexion_min_deg, g.hip_flexion_max_deg,
                g.max_jump_deg, g.max_jump_coordinate.c_str(), g.max_jump_frame);
  out += line;
  return out;
}

}  // namespace fabrik::eval
