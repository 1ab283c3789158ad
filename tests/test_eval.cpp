// fabrik eval: the evaluations on synthetic data with known answers, and the
// must-show accuracy on the real subject01 recordings when ../shared/data is there.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numbers>
#include <random>
#include <string>

#include "eval/eval.hpp"
#include "offline/solve_trial.hpp"
#include "synth/synthetic_motion.hpp"

namespace {

using namespace fabrik;

// A noise-free recording of the default config's model, every marker visible.
io::MarkerTrial synthetic_trial(const DaemonConfig& config, double seconds, double rate_hz) {
  const Model& model = *config.tracker.model;
  std::vector<int> points;
  io::MarkerTrial trial;
  trial.rate_hz = rate_hz;
  for (const MarkerTarget& m : config.tracker.markers) {
    points.push_back(m.point);
    trial.labels.push_back(m.marker);
  }
  SyntheticMotion motion(model, MotionSettings{});
  Posture posture = Posture::rest(model);
  std::vector<Eigen::Vector3d> frame(points.size());
  for (int f = 0; f < static_cast<int>(seconds * rate_hz); ++f) {
    motion.posture_at(f / rate_hz, posture);
    motion.sample(posture, points, 0.0, frame);
    trial.positions_m.insert(trial.positions_m.end(), frame.begin(), frame.end());
  }
  return trial;
}

}  // namespace

TEST_CASE("gap evaluation: a marker of a rigid cluster is predicted from its neighbours") {
  const DaemonConfig config = default_daemon_config();
  const io::MarkerTrial trial = synthetic_trial(config, 2.0, 100.0);
  eval::GapOptions options;
  options.windows_s = {0.5, 1.0};
  options.markers = {"RTHF", "LTIB", "STRN"};  // thigh, shank and torso: three markers or more
  const eval::GapReport r = eval::eval_gaps(config, trial, options);
  REQUIRE(r.rows.size() == 12);  // live and offline
  for (const eval::GapStats& g : r.rows) {
    INFO(g.marker << " " << g.window_s << " s: RMS " << g.rms_m * 1e3 << " mm");
    CHECK(g.windows >= 2);
    CHECK(g.samples > 0);
    // The weak prediction pull (weight 0.05 on the markers' level) biases a
    // segment its other markers determine by a millimetre or two.
    CHECK(g.rms_m < 3e-3);
    CHECK(g.joint_rms_m < 3e-3);
    CHECK(g.return_jump_m < 3e-3);
  }
  REQUIRE(r.summary.size() == 4);
  CHECK(r.summary[1].median_rms_m < 3e-3);
  CHECK(r.summary[3].median_rms_m < 3e-3);
  CHECK_FALSE(r.traces.empty());
}

TEST_CASE("reduction evaluation: an empty drop set deviates by nothing, a drop by something") {
  const DaemonConfig config = default_daemon_config();
  const io::MarkerTrial trial = synthetic_trial(config, 1.0, 100.0);
  const auto rows = eval::eval_reduction(
      config, trial, {{"none", {}}, {"no right thigh front", {"RTHF", "RTHI"}}});
  REQUIRE(rows.size() == 2);
  CHECK(rows[0].kept == static_cast<int>(config.tracker.markers.size()));
  CHECK(rows[0].rms_m == 0.0);
  CHECK(rows[0].max_m == 0.0);
  for (const auto& g : rows[0].groups) CHECK(g.max_m == 0.0);
  CHECK(rows[1].kept == rows[0].kept - 2);
  CHECK(rows[1].max_m > 0.0);
  CHECK_THROWS_AS(eval::eval_reduction(config, trial, {{"typo", {"RTHX"}}}), std::invalid_argument);
}

TEST_CASE("synthetic evaluation: joint centres within 2 mm RMS of the truth at 1 mm noise") {
  eval::SyntheticOptions options;
  options.noise_mm = {0.0, 1.0};
  options.seconds = 3.0;
  const auto rows = eval::eval_synthetic(default_daemon_config(), options);
  REQUIRE(rows.size() == 2);
  CHECK(rows[0].joint_rms_m < rows[1].joint_rms_m);
  CHECK(rows[1].joint_rms_m < 2e-3);
  CHECK(rows[1].joint_p99_m >= rows[1].joint_rms_m);
}

TEST_CASE("real data: subject01 walk1 residuals and 1 s gaps (skipped without ../shared/data)") {
  const std::string dir = FABRIK_SHARED_DATA_DIR;
  const std::string stat = dir + "/subject01_static.trc", walk = dir + "/subject01_walk1.trc";
  if (!std::filesystem::exists(stat) || !std::filesystem::exists(walk)) {
    WARN("SKIPPED: " << stat << " or " << walk << " is absent (real data lives in ../shared/data)");
    return;
  }
  const DaemonConfig config = eval::calibrate_config(
      std::string(FABRIK_SOURCE_DIR) + "/config/templates/gait2354.json", stat);
  const io::MarkerTrial trial = io::read_trial(walk);

  const eval::WalkReport w = eval::eval_walk(config, trial);
  INFO("walk: mean RMS " << w.rms_mean_m * 1e3 << " mm, max " << w.max_m_over_frames * 1e3
                         << " mm (" << w.max_marker << ")");
  CHECK(w.rms_m.size() == trial.frames());
  CHECK(w.rms_mean_m <= 10e-3);
  // The per-frame maximum (<= 30 mm with joint limits) is checked, and known to
  // fail today, in test_angles.cpp's must-show.
  // No rigid model can fit a marker better than its own segment's markers alone allow.
  CHECK(w.max_m_over_frames >= w.cluster_max_over_frames_m - 1e-9);

  eval::GapOptions options;
  options.windows_s = {1.0};
  options.modes = {eval::GapMode::live};
  const eval::GapReport g = eval::eval_gaps(config, trial, options);
  REQUIRE(g.summary.size() == 1);
  INFO("1 s gaps: median RMS " << g.summary[0].median_rms_m * 1e3 << " mm");
  CHECK(g.summary[0].markers == static_cast<int>(config.tracker.markers.size()));
  CHECK(g.summary[0].median_rms_m <= 15e-3);
}

TEST_CASE("IMUs on synthetic truth: 1 deg noise, IMU-only joint angles within 3 deg RMS",
          "[eval][sensors]") {
  eval::ImuSyntheticOptions o;
  o.seconds = 3.0;
  const auto rows = eval::eval_imu_synthetic(default_daemon_config(), o);
  REQUIRE(rows.size() == 3);
  CHECK(rows[1].sensors == 15);
  CHECK(rows[1].markers == 0);
  CHECK(rows[1].joint_angle_rms_rad * 180 / 3.141592653589793 < 3.0);
  CHECK(rows[2].markers == 4);
  CHECK(rows[2].joint_angle_rms_rad * 180 / 3.141592653589793 < 3.0);
}

TEST_CASE("real data: the OpenSense walk from its 8 IMUs (skipped without ../shared/data)",
          "[eval][sensors]") {
  const std::string dir = std::string(FABRIK_SHARED_DATA_DIR) + "/";
  const std::string stat = dir + "subject01_static.trc",
                    placement = dir + "opensense_placement_orientations.sto",
                    walk = dir + "opensense_walking_orientations.sto";
  if (!std::filesystem::exists(stat) || !std::filesystem::exists(walk)) {
    WARN("SKIPPED: " << walk << " is absent (real data lives in ../shared/data)");
    return;
  }
  const eval::OpenSenseRun run = eval::eval_imu_opensense(
      std::string(FABRIK_SOURCE_DIR) + "/config/templates/opensense_gait2354.json", stat,
      placement, walk);
  const eval::GaitReport& g = run.report;
  CHECK(g.frames == 2432);
  CHECK(g.frames_tracked == g.frames);
  CHECK(g.strides.size() >= 20);
  for (const eval::GaitStride& s : g.strides) {
    CAPTURE(s.side, s.time_s);
    CHECK(s.knee_flexion_deg >= 50.0);
    CHECK(s.knee_flexion_deg <= 80.0);
  }
  CHECK(g.alternating);
  CHECK(g.knee_flexion_min_deg >= -5.0 - 1e-6);  // the knee's hyperextension limit
  CHECK(g.hip_flexion_min_deg >= -30.0);
  CHECK(g.hip_flexion_max_deg <= 45.0);
  CHECK(g.max_jump_deg <= 10.0);
}

TEST_CASE(
    "solve's markers are the measurements with their gaps filled, the model's fitted "
    "markers apart",
    "[gaps]") {
  const DaemonConfig config = default_daemon_config();
  io::MarkerTrial trial = synthetic_trial(config, 2.0, 100.0);
  const std::size_t n = trial.markers(), frames = trial.frames();
  std::mt19937 random(7);
  std::normal_distribution<double> noise_m(0.0, 2e-3);  // what the fit smooths out
  for (Eigen::Vector3d& p : trial.positions_m)
    p += Eigen::Vector3d(noise_m(random), noise_m(random), noise_m(random));
  const std::size_t gapped = 5, never = 9, gap_first = 80, gap_end = 120;
  for (std::size_t f = 0; f < frames; ++f) {
    if (f >= gap_first && f < gap_end) trial.positions_m[f * n + gapped].setConstant(NAN);
    trial.positions_m[f * n + never].setConstant(NAN);
  }
  const TrialSolution s = solve_trial(config, trial);
  REQUIRE(s.markers.labels == trial.labels);
  REQUIRE(s.model_markers.labels == trial.labels);
  double model_off_m = 0.0;
  for (std::size_t f = 0; f < frames; ++f)
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d& measured = trial.at(f, static_cast<int>(i));
      CHECK(s.model_markers.at(f, static_cast<int>(i)).allFinite());
      if (i == never) {
        CHECK_FALSE(s.markers.at(f, static_cast<int>(i)).allFinite());  // nothing invented
      } else if (!measured.allFinite()) {
        CHECK(s.markers.at(f, static_cast<int>(i)).allFinite());  // filled
      } else {
        CHECK(s.markers.at(f, static_cast<int>(i)) == measured);  // as measured, exactly
        model_off_m =
            std::max(model_off_m, (s.model_markers.at(f, static_cast<int>(i)) - measured).norm());
      }
    }
  CHECK(model_off_m > 1e-3);  // the model's markers are the fit's, not the measurements
  REQUIRE(s.filled.size() == 1);
  CHECK(s.filled[0].marker == trial.labels[gapped]);
  CHECK(s.filled[0].first == gap_first);
  CHECK(s.filled[0].end == gap_end);
}

TEST_CASE("The IMU gait report reads a walk whose first frames have no pose (NaN)", "[eval][imu]") {
  // A knee swinging twice (60 deg peaks), the first 5 frames without a pose: NaN, as
  // solve_trial writes frames before the first measurement (the report looped for ever on them).
  fabrik::TrialSolution s;
  s.coordinate_names = {"knee_angle_r", "hip_flexion_r"};
  s.coordinate_is_rotation = {1, 1};
  s.joints.rate_hz = 100.0;
  const std::size_t frames = 200;
  const double deg = std::numbers::pi / 180.0;
  for (std::size_t f = 0; f < frames; ++f) {
    const bool posed = f >= 5;
    const double knee_deg = -30.0 - 30.0 * std::sin(2.0 * std::numbers::pi * f / 100.0);
    s.coordinates.push_back(posed ? knee_deg * deg : std::numeric_limits<double>::quiet_NaN());
    s.coordinates.push_back(posed ? 10.0 * deg : std::numeric_limits<double>::quiet_NaN());
    s.status.push_back(posed ? "converged" : "no_targets");
  }
  const fabrik::eval::GaitReport g = fabrik::eval::gait_report(s);
  CHECK(g.frames == frames);
  REQUIRE(g.strides.size() == 2);
  for (const fabrik::eval::GaitStride& stride : g.strides)
    CHECK(stride.knee_flexion_deg == Approx(60.0).margin(0.1));
  CHECK(g.hip_flexion_max_deg == Approx(10.0));
}
