// Outlier markers (swapped labels, ghosts, stray zeros) left out of the solve, no false
// alarms on real walking and fast synthetic motion, cold starts that converge, and the fit
// verdict (residual.quality). Real-data cases skip without ../shared/data.
#include <unistd.h>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>

#include "config/daemon_config.hpp"
#include "eval/subject.hpp"
#include "io/marker_trial.hpp"
#include "offline/solve_trial.hpp"
#include "synth/synthetic_motion.hpp"
#include "tracking/cold_start.hpp"
#include "tracking/mirror_swap.hpp"
#include "tracking/outlier_filter.hpp"
#include "tracking/tracker.hpp"

using namespace fabrik;
using fabrik::io::MarkerTrial;

namespace {

const std::string kDataDir = FABRIK_SOURCE_DIR "/../shared/data";
const std::string kSourceDir = FABRIK_SOURCE_DIR;

bool have_walk() {
  if (std::filesystem::exists(kDataDir + "/subject01_walk1.trc")) return true;
  WARN("skipped: " << kDataDir << "/subject01_walk1.trc not found");
  return false;
}

const DaemonConfig& walk_config() {
  static const DaemonConfig c = eval::calibrate_config(
      kSourceDir + "/config/templates/gait2354.json", kDataDir + "/subject01_static.trc");
  return c;
}

const MarkerTrial& walk() {
  static const MarkerTrial t = io::read_trial(kDataDir + "/subject01_walk1.trc");
  return t;
}

double joint_distance_m(const TrialSolution& a, const TrialSolution& b, std::size_t f,
                        std::size_t j) {
  const std::size_t n = a.joints.labels.size();
  return (a.joints.positions_m[f * n + j] - b.joints.positions_m[f * n + j]).norm();
}

std::vector<int> marker_points(const DaemonConfig& config) {
  std::vector<int> points;
  for (const MarkerTarget& m : config.tracker.markers) points.push_back(m.point);
  return points;
}

double outlier_percent(const TrialSolution& s) {
  std::size_t flagged = 0, measured = 0;
  for (std::uint8_t o : s.outlier) flagged += o;
  for (int m : s.measured) measured += static_cast<std::size_t>(m);
  return 100.0 * static_cast<double>(flagged) / static_cast<double>(measured);
}

// Swaps two labels' samples in frames [first, first + count) and checks the issue's bar:
// both flagged in >= 90 % of those frames, every joint centre within 10 mm of the unswapped
// solve in every frame.
void check_swap(const std::string& a, const std::string& b, std::size_t first, std::size_t count,
                const DaemonConfig& config) {
  MarkerTrial swapped = walk();
  const int ca = swapped.find(a), cb = swapped.find(b);
  REQUIRE(ca >= 0);
  REQUIRE(cb >= 0);
  for (std::size_t f = first; f < first + count; ++f)
    std::swap(swapped.at(f, std::size_t(ca)), swapped.at(f, std::size_t(cb)));
  const TrialSolution reference = solve_trial(config, walk());
  const TrialSolution s = solve_trial(config, swapped);
  const std::size_t n = s.markers.labels.size();
  int ia = -1, ib = -1;
  for (std::size_t i = 0; i < n; ++i) {
    if (s.markers.labels[i] == a) ia = static_cast<int>(i);
    if (s.markers.labels[i] == b) ib = static_cast<int>(i);
  }
  REQUIRE(ia >= 0);
  REQUIRE(ib >= 0);
  std::size_t flagged = 0;
  for (std::size_t f = first; f < first + count; ++f)
    flagged += s.outlier[f * n + ia] + s.outlier[f * n + ib];
  INFO(a << " <-> " << b);
  CHECK(static_cast<double>(flagged) >= 0.9 * 2.0 * static_cast<double>(count));
  double worst_m = 0.0;
  for (std::size_t f = 0; f < s.rms_m.size(); ++f)
    for (std::size_t j = 0; j < s.joints.labels.size(); ++j)
      worst_m = std::max(worst_m, joint_distance_m(s, reference, f, j));
  WARN(a << " <-> " << b << ": " << flagged << " of " << 2 * count
         << " swapped samples flagged; joint centres at most " << worst_m * 1e3
         << " mm from the unswapped solve");
  CHECK(worst_m <= 10e-3);
}

// Tracks `frames` frames of the default config's synthetic motion (100 Hz, 1 mm noise) twice:
// once as sampled, once with spoil(f, markers) applied, then judge(f, result) of the spoilt
// one. Returns the largest joint-centre distance between the two (m).
template <class Spoil, class Judge>
double track_spoilt(int frames, Spoil spoil, Judge judge) {
  const DaemonConfig config = default_daemon_config();
  const Model& model = *config.tracker.model;
  SyntheticMotion motion(model, {});
  const std::vector<int> points = marker_points(config);
  Tracker tracker(config.tracker), clean(config.tracker);
  Posture truth = Posture::rest(model);
  std::vector<Eigen::Vector3d> measured(points.size()), bad(points.size());
  std::vector<std::uint8_t> visible(points.size(), 1);
  double worst_m = 0.0;
  for (int f = 0; f < frames; ++f) {
    const double t = f / 100.0;
    motion.posture_at(t, truth);
    motion.sample(truth, points, 0.001, measured);
    bad = measured;
    spoil(f, bad);
    judge(f, tracker.track(t, bad, visible));
    clean.track(t, measured, visible);
    for (std::size_t j = 0; j < model.joints.size(); ++j)
      worst_m = std::max(worst_m, (tracker.posture().point_world_m(model, model.joints[j].point) -
                                   clean.posture().point_world_m(model, model.joints[j].point))
                                      .norm());
  }
  return worst_m;
}

}  // namespace

TEST_CASE("walk1 with two labels swapped for 20 frames: flagged, joints stay", "[outliers]") {
  if (!have_walk()) return;
  check_swap("R.Thigh.Front", "R.Shank.Front", 60, 20, walk_config());
  check_swap("L.Wrist.Lat", "L.Elbow", 60, 20, walk_config());
  check_swap("R.Thigh.Front", "R.Shank.Front", 0, 20, walk_config());  // from the first frame
}

TEST_CASE("walk1 with a label swap and the outlier rule off: the skeleton is dragged",
          "[outliers]") {
  if (!have_walk()) return;
  DaemonConfig off = walk_config();
  off.tracker.outliers.enabled = false;
  MarkerTrial swapped = walk();
  const int ca = swapped.find("L.Wrist.Lat"), cb = swapped.find("L.Elbow");
  for (std::size_t f = 60; f < 80; ++f)
    std::swap(swapped.at(f, std::size_t(ca)), swapped.at(f, std::size_t(cb)));
  const TrialSolution reference = solve_trial(off, walk());
  const TrialSolution s = solve_trial(off, swapped);
  double worst_m = 0.0;
  for (std::size_t f = 60; f < 80; ++f)
    for (std::size_t j = 0; j < s.joints.labels.size(); ++j)
      worst_m = std::max(worst_m, joint_distance_m(s, reference, f, j));
  CHECK(worst_m > 30e-3);  // what the rule prevents
}

TEST_CASE("walk1 unswapped: outliers in under 0.5 % of marker samples", "[outliers]") {
  if (!have_walk()) return;
  const TrialSolution s = solve_trial(walk_config(), walk());
  WARN("walk1: outliers in " << outlier_percent(s) << " % of marker samples");
  CHECK(outlier_percent(s) < 0.5);
}

TEST_CASE("fast synthetic motion (running pace): outliers in under 0.5 % of marker samples",
          "[outliers]") {
  const DaemonConfig config = default_daemon_config();
  const Model& model = *config.tracker.model;
  // About a running stride: 1.5 strides a second, wide swings, the root travelling 3 m.
  SyntheticMotion motion(model, {.seed = 7,
                                 .frequency_hz = 1.5,
                                 .max_swing_rad = 1.2,
                                 .root_travel_m = 3.0,
                                 .root_turn_rad = 0.5});
  const std::vector<int> points = marker_points(config);
  Tracker tracker(config.tracker);
  Posture truth = Posture::rest(model);
  std::vector<Eigen::Vector3d> measured(points.size());
  std::vector<std::uint8_t> visible(points.size(), 1);
  std::size_t flagged = 0, samples = 0;
  double worst_rms_m = 0.0;
  for (int f = 0; f < 1000; ++f) {  // 10 s at 100 Hz
    const double t = f / 100.0;
    motion.posture_at(t, truth);
    motion.sample(truth, points, 0.001, measured);
    const TrackResult& r = tracker.track(t, measured, visible);
    flagged += static_cast<std::size_t>(r.outlier_count);
    samples += points.size();
    worst_rms_m = std::max(worst_rms_m, r.residual_rms_m);
  }
  const double percent = 100.0 * static_cast<double>(flagged) / static_cast<double>(samples);
  WARN("fast synthetic: outliers in " << percent << " % of marker samples; worst frame RMS "
                                      << worst_rms_m * 1e3 << " mm");
  CHECK(percent < 0.5);
}

TEST_CASE("A ghost (a marker 30 cm off) and a stray zero are left out, live as offline",
          "[outliers]") {
  const int ghost = 12, zero = 30;
  int ghost_flagged = 0, zero_flagged = 0, frames = 0;
  const auto spoiled = [](int f) { return f >= 40 && f < 60; };
  const double worst_m = track_spoilt(
      100,
      [&](int f, std::vector<Eigen::Vector3d>& bad) {
        if (!spoiled(f)) return;
        bad[ghost] += Eigen::Vector3d(0.3, 0.0, 0.0);
        bad[zero].setZero();  // as if zero_is_missing were off
      },
      [&](int f, const TrackResult& r) {
        if (!spoiled(f)) return;
        ++frames;
        ghost_flagged += r.outliers[ghost];
        zero_flagged += r.outliers[zero];
        CHECK(r.relabelled_from[ghost] == -1);
      });
  CHECK(ghost_flagged == frames);
  CHECK(zero_flagged == frames);
  CHECK(worst_m < 5e-3);
}

TEST_CASE("A root marker metres off is left out, not followed: judged against the prediction",
          "[outliers]") {
  const DaemonConfig config = default_daemon_config();
  const Model& model = *config.tracker.model;
  const std::vector<int> points = marker_points(config);
  std::vector<int> root_markers;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (model.points[points[i]].segment == 0) root_markers.push_back(static_cast<int>(i));
  REQUIRE(root_markers.size() >= 3);
  const int spoilt = GENERATE_COPY(from_range(root_markers));
  const double off_m = GENERATE(0.3, 10.0);
  CAPTURE(config.tracker.markers[spoilt].marker, off_m);
  int flagged = 0, frames = 0;
  const double worst_m = track_spoilt(
      60,
      [&](int f, std::vector<Eigen::Vector3d>& bad) {
        if (f >= 30) bad[spoilt] += Eigen::Vector3d(0.0, off_m, 0.0);
      },
      [&](int f, const TrackResult& r) {
        if (f < 30) return;
        ++frames;
        flagged += r.outliers[spoilt];
      });
  CHECK(flagged == frames);
  CHECK(worst_m < 5e-3);
}

TEST_CASE("A cold frame's solve takes the cold budget, at least the fallback carry and anchors",
          "[cold_start]") {
  SolverOptions warm;
  ColdStartSettings cold;
  warm.max_iterations = 50;
  cold.max_iterations = 500;
  warm.subtree_carry = 0.0;
  warm.fallback_carry = 0.5;
  SolverOptions o = cold_solver_options(warm, cold);
  CHECK(o.max_iterations == 500);
  CHECK(o.subtree_carry == 0.5);
  // A carry above the fallback's is kept; FABRIK's own rule (both 0) stays FABRIK's.
  warm.subtree_carry = 1.0;
  CHECK(cold_solver_options(warm, cold).subtree_carry == 1.0);
  warm.subtree_carry = 0.0;
  warm.fallback_carry = 0.0;
  CHECK(cold_solver_options(warm, cold).subtree_carry == 0.0);
  // Anchors at least 1 (none, or weak ones, are raised); stronger ones kept.
  warm.anchor_weight = 0.0;
  CHECK(cold_solver_options(warm, cold).anchor_weight == 1.0);
  warm.anchor_weight = 0.1;
  CHECK(cold_solver_options(warm, cold).anchor_weight == 1.0);
  // The rest of the options are the warm frame's.
  warm.anchor_weight = 7.0;
  warm.tolerance_m = 2e-4;
  o = cold_solver_options(warm, cold);
  CHECK(o.anchor_weight == 7.0);
  CHECK(o.tolerance_m == 2e-4);
}

TEST_CASE("walk1's first frame converges: max residual <= 25 mm, also from far away",
          "[cold_start]") {
  if (!have_walk()) return;
  const DaemonConfig& config = walk_config();
  const TrialSolution s = solve_trial(config, walk());
  WARN("walk1 first frame: max " << s.max_m[0] * 1e3 << " mm, " << s.iterations[0]
                                 << " iterations");
  CHECK(s.max_m[0] <= 25e-3);
  // The subject turned 90 deg about the vertical (Y) and 2 m away from the rest posture.
  MarkerTrial moved = walk();
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()).matrix();
  for (Eigen::Vector3d& p : moved.positions_m)
    if (p.allFinite()) p = turn * p + Eigen::Vector3d(2.0, 0.0, 0.0);
  const TrialSolution m = solve_trial(config, moved);
  WARN("walk1 turned 90 deg, 2 m away: first frame max " << m.max_m[0] * 1e3 << " mm, "
                                                          << m.iterations[0] << " iterations");
  CHECK(m.max_m[0] <= 25e-3);
  double worst_diff_m = 0.0;
  for (std::size_t f = 0; f < s.max_m.size(); ++f)
    worst_diff_m = std::max(worst_diff_m, std::abs(m.max_m[f] - s.max_m[f]));
  CHECK(worst_diff_m < 1e-3);  // every frame fits as well as the untouched trial's

}

TEST_CASE("A cold first frame of a bent posture, turned and far away, converges",
          "[cold_start]") {
  const DaemonConfig config = default_daemon_config();
  const Model& model = *config.tracker.model;
  const std::vector<int> points = marker_points(config);
  std::vector<Eigen::Vector3d> measured(points.size());
  std::vector<std::uint8_t> visible(points.size(), 1);
  DaemonConfig warm_only = config;  // the warm frame's budget, from the rest posture as it is
  warm_only.tracker.cold_start.max_iterations = 1;
  warm_only.tracker.cold_start.align = false;
  double worst_cold_m = 0.0, worst_warm_only_m = 0.0;
  for (unsigned seed = 1; seed <= 8; ++seed) {
    SyntheticMotion motion(model, {.seed = seed, .max_swing_rad = 1.2, .root_travel_m = 0.0,
                                   .root_turn_rad = 0.0});
    Posture truth = Posture::rest(model);
    motion.posture_at(0.37 * seed, truth);
    motion.sample(truth, points, 0.0, measured);
    const double turn_rad = M_PI / 4 * seed;  // 45 deg to 360 deg
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(turn_rad, Eigen::Vector3d::UnitY()).matrix();
    for (Eigen::Vector3d& p : measured) p = turn * p + Eigen::Vector3d(2.0, 0.0, 1.0);
    Tracker cold(config.tracker), plain(warm_only.tracker);
    worst_cold_m = std::max(worst_cold_m, cold.track(0.0, measured, visible).residual_max_m);
    worst_warm_only_m =
        std::max(worst_warm_only_m, plain.track(0.0, measured, visible).residual_max_m);
  }
  WARN("first frame, bent and turned 45-360 deg, 2.2 m away: max residual " << worst_cold_m * 1e3
       << " mm cold-started, " << worst_warm_only_m * 1e3 << " mm with the warm budget alone");
  CHECK(worst_cold_m < 5e-3);
}

TEST_CASE("A reset and a long gap start cold, a short gap does not", "[cold_start]") {
  const DaemonConfig config = default_daemon_config();
  const Model& model = *config.tracker.model;
  SyntheticMotion motion(model, {});
  const std::vector<int> points = marker_points(config);
  Tracker tracker(config.tracker);
  Posture truth = Posture::rest(model);
  std::vector<Eigen::Vector3d> measured(points.size());
  std::vector<std::uint8_t> visible(points.size(), 1);
  const auto frame = [&](double t, double shift_m) {
    motion.posture_at(t, truth);
    motion.sample(truth, points, 0.0, measured);
    for (Eigen::Vector3d& p : measured) p.x() += shift_m;
    return tracker.track(t, measured, visible);
  };
  CHECK(frame(0.0, 0.0).cold_start);
  CHECK_FALSE(frame(0.01, 0.0).cold_start);
  CHECK_FALSE(frame(0.3, 0.0).cold_start);  // a short gap
  // After a long gap the subject is elsewhere: a cold start finds it.
  const TrackResult& far = frame(5.0, 3.0);
  CHECK(far.cold_start);
  CHECK(far.residual_max_m < 5e-3);
  tracker.reset();
  CHECK(frame(5.01, 3.0).cold_start);
}

TEST_CASE("The outlier bar is the larger of the floor and median_factor times the others' median",
          "[outliers]") {
  const OutlierSettings s;  // floor 60 mm, median factor 8
  OutlierFilter filter(s, std::vector<int>(8, 0));
  const std::vector<std::uint8_t> visible(8, 1);
  // The seven others' median is 10 mm (their mean 12.3 mm, their largest 30 mm):
  // the bar is 8 x 10 = 80 mm, above the floor.
  std::vector<double> residual_m = {0.002, 0.004, 0.006, 0.0, 0.010, 0.014, 0.020, 0.030};
  const double bar_m = s.median_factor * 0.010;
  REQUIRE(bar_m > s.floor_m);
  residual_m[3] = bar_m - 0.005;  // beyond the floor, within the bar
  CHECK(filter.worst_outlier(residual_m, visible) == -1);
  CHECK(filter.bar_m() == Approx(bar_m));
  residual_m[3] = bar_m + 0.005;
  CHECK(filter.worst_outlier(residual_m, visible) == 3);

  // Others fitting to a few millimetres: the floor is the bar.
  for (double& r : residual_m) r *= 0.5;
  REQUIRE(s.median_factor * 0.005 < s.floor_m);
  residual_m[3] = s.floor_m + 0.005;
  CHECK(filter.worst_outlier(residual_m, visible) == 3);
  CHECK(filter.bar_m() == Approx(s.floor_m));
  residual_m[3] = s.floor_m - 0.005;
  CHECK(filter.worst_outlier(residual_m, visible) == -1);

  // Judged by other distances (to the frame's prediction), a marker whose own residual is
  // within the floor is no outlier, however far from the prediction (a review's probe once
  // saw clean markers flagged so).
  std::vector<double> start_m(8, 0.004);
  start_m[5] = 0.5;
  std::vector<double> solve_m(8, 0.004);
  solve_m[5] = s.floor_m + 0.001;
  CHECK(filter.worst_outlier(start_m, visible, {}, solve_m) == 5);
  solve_m[5] = s.floor_m - 0.001;
  CHECK(filter.worst_outlier(start_m, visible, {}, solve_m) == -1);
}

TEST_CASE("No marker is judged an outlier with fewer than six measured (the default min_markers)",
          "[outliers]") {
  OutlierFilter filter(OutlierSettings{}, std::vector<int>(7, 0));
  // Six fit to 5 mm and one is a metre off: far beyond any bar.
  const std::vector<double> residual_m = {1.0, 0.005, 0.005, 0.005, 0.005, 0.005, 0.005};
  std::vector<std::uint8_t> visible(7, 1);
  visible[6] = 0;  // six measured: judged
  CHECK(filter.worst_outlier(residual_m, visible) == 0);
  visible[5] = 0;  // five: too few to tell which one is wrong
  CHECK(filter.worst_outlier(residual_m, visible) == -1);
}

TEST_CASE("residual.quality: good within the config's thresholds, poor beyond, none without "
          "markers",
          "[quality]") {
  DaemonConfig config = default_daemon_config();
  const Model& model = *config.tracker.model;
  SyntheticMotion motion(model, {});
  const std::vector<int> points = marker_points(config);
  Posture truth = Posture::rest(model);
  motion.posture_at(0.3, truth);
  std::vector<Eigen::Vector3d> measured(points.size());
  motion.sample(truth, points, 0.0, measured);
  measured[5] += Eigen::Vector3d(0.0, 0.025, 0.0);  // one marker 25 mm off: not an outlier
  std::vector<std::uint8_t> visible(points.size(), 1);
  {
    Tracker tracker(config.tracker);
    const TrackResult& r = tracker.track(0.0, measured, visible);
    CHECK(r.outlier_count == 0);
    CHECK(r.quality == FitQuality::good);
    CHECK(r.beyond_count == 0);
  }
  config.tracker.quality.max_m = 0.010;
  {
    Tracker tracker(config.tracker);
    const TrackResult& r = tracker.track(0.0, measured, visible);
    CHECK(r.quality == FitQuality::poor);
    CHECK(r.beyond_count >= 1);
    CHECK(r.beyond[5] == 1);
    std::fill(visible.begin(), visible.end(), 0);
    CHECK(tracker.track(0.01, measured, visible).quality == FitQuality::none);
  }
}

TEST_CASE("Config: outliers, quality and cold_start are read in mm and checked", "[config]") {
  const std::string base = R"({"format": "fabrikd-config/1", "model": "models/fullbody.json",)";
  const DaemonConfig c = load_daemon_config(
      base + R"("outliers": {"floor_mm": 80, "median_factor": 6, "max_per_frame": 2,
                 "relabel_swaps": false}, "quality": {"rms_mm": 15, "max_mm": 30},
                 "cold_start": {"max_iterations": 300, "after_gap_s": 1.5, "align": false}})",
      "<embedded>/test.json");
  CHECK(c.tracker.outliers.floor_m == Approx(0.080));
  CHECK(c.tracker.outliers.median_factor == 6.0);
  CHECK(c.tracker.outliers.max_per_frame == 2);
  CHECK_FALSE(c.tracker.outliers.relabel_swaps);
  CHECK(c.tracker.quality.rms_m == Approx(0.015));
  CHECK(c.tracker.quality.max_m == Approx(0.030));
  CHECK(c.tracker.cold_start.max_iterations == 300);
  CHECK(c.tracker.cold_start.after_gap_s == 1.5);
  CHECK_FALSE(c.tracker.cold_start.align);
  CHECK_THROWS_WITH(
      load_daemon_config(base + R"("outliers": {"floor": 80}})", "<embedded>/test.json"),
      Catch::Contains("/outliers") && Catch::Contains("floor_mm"));
}

namespace {

// walk1 with each forearm's wrist markers turned about the elbow-to-wrist line
// by a pronation wave of +-`amplitude_rad` (one cycle a second): what a
// runner's forearms do, which a hinge elbow cannot follow.
MarkerTrial pronating_walk(double amplitude_rad) {
  MarkerTrial t = walk();
  for (const char* side : {"R", "L"}) {
    const std::string s(side);
    const int elbow = t.find(s + ".Elbow"), med = t.find(s + ".Wrist.Med"),
              lat = t.find(s + ".Wrist.Lat");
    REQUIRE((elbow >= 0 && med >= 0 && lat >= 0));
    for (std::size_t f = 0; f < t.frames(); ++f) {
      Eigen::Vector3d& m = t.at(f, std::size_t(med));
      Eigen::Vector3d& l = t.at(f, std::size_t(lat));
      const Eigen::Vector3d mid = 0.5 * (m + l);
      const Eigen::Vector3d axis = (mid - t.at(f, std::size_t(elbow))).normalized();
      const double angle = amplitude_rad * std::sin(2.0 * M_PI * static_cast<double>(f) / t.rate_hz);
      const Eigen::AngleAxisd turn(angle, axis);
      m = mid + turn * (m - mid);
      l = mid + turn * (l - mid);
    }
  }
  return t;
}

// gait2354 with its elbows made hinges again (no pronation).
const DaemonConfig& hinge_elbow_config() {
  static const DaemonConfig c = [] {
    std::ifstream in(kSourceDir + "/config/templates/gait2354.json");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string ball = R"("type": "ball",
        "range_deg": {"z": [-5, 150], "x": [-10, 10], "y": [-90, 90]},)";
    const std::string hinge = R"("type": "hinge",
        "range_deg": {"z": [-5, 150]},)";
    for (int k = 0; k < 2; ++k) {
      const std::size_t at = text.find(ball);
      REQUIRE(at != std::string::npos);
      text.replace(at, ball.size(), hinge);
    }
    const std::string path = (std::filesystem::temp_directory_path() /
                              ("fabrik_hinge_elbow_" + std::to_string(::getpid()) + ".json"))
                                 .string();
    std::ofstream(path) << text;
    DaemonConfig config = eval::calibrate_config(path, kDataDir + "/subject01_static.trc");
    std::filesystem::remove(path);
    return config;
  }();
  return c;
}

// Flagged samples of the wrist markers, and their largest residual (the model's fitted
// marker against the measurement).
std::pair<std::size_t, double> wrist_flags(const TrialSolution& s, const MarkerTrial& trial) {
  std::size_t flagged = 0;
  double worst_m = 0.0;
  const std::size_t n = s.markers.labels.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (s.markers.labels[i].find("Wrist") == std::string::npos) continue;
    const int k = trial.find(s.markers.labels[i]);
    REQUIRE(k >= 0);
    for (std::size_t f = 0; f < s.rms_m.size(); ++f) {
      flagged += s.outlier[f * n + i];
      worst_m = std::max(worst_m, (s.model_markers.at(f, i) - trial.at(f, std::size_t(k))).norm());
    }
  }
  return {flagged, worst_m};
}

}  // namespace

TEST_CASE("Pronating forearms: wrist markers are never flagged, with or without a pronation joint",
          "[outliers]") {
  if (!have_walk()) return;
  const MarkerTrial trial = pronating_walk(70.0 * M_PI / 180.0);
  // The shipped template's forearms pronate: the wrist markers fit.
  const TrialSolution fits = solve_trial(walk_config(), trial);
  const auto [flagged_fit, worst_fit_m] = wrist_flags(fits, trial);
  // A hinge elbow cannot follow them: residuals beyond the outlier bar (set low
  // here, 15 mm, so that the misfit alone would flag them), yet each wrist
  // marker keeps its distances to the markers around it.
  DaemonConfig hinge_config = hinge_elbow_config();
  hinge_config.tracker.outliers.floor_m = 0.015;
  hinge_config.tracker.outliers.median_factor = 1.0;
  const TrialSolution hinge = solve_trial(hinge_config, trial);
  const auto [flagged_hinge, worst_hinge_m] = wrist_flags(hinge, trial);
  WARN("pronation +-70 deg: wrist samples flagged " << flagged_fit << " (pronating elbows, worst "
       << "wrist residual " << worst_fit_m * 1e3 << " mm), " << flagged_hinge
       << " (hinge elbows, worst " << worst_hinge_m * 1e3 << " mm)");
  CHECK(flagged_fit == 0);
  CHECK(worst_fit_m < 30e-3);
  REQUIRE(worst_hinge_m > 2.0 * hinge_config.tracker.outliers.floor_m);  // the rule is challenged
  CHECK(flagged_hinge == 0);
}

TEST_CASE("Marker neighbours: a marker moved when its distances to half its neighbours break",
          "[outliers]") {
  const DaemonConfig config = default_daemon_config();
  const Model& model = *config.tracker.model;
  const std::vector<int> points = marker_points(config);
  const MarkerNeighbours neighbours(model, points);
  const Posture rest = Posture::rest(model);
  std::vector<Eigen::Vector3d> at_m(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) at_m[i] = rest.point_world_m(model, points[i]);
  std::vector<std::uint8_t> visible(points.size(), 1);
  const int knee = static_cast<int>(
      std::find_if(points.begin(), points.end(),
                   [&](int p) { return model.points[p].name == "RKNE"; }) - points.begin());
  REQUIRE(knee < static_cast<int>(points.size()));
  REQUIRE(neighbours.neighbour_count(knee) >= 2);
  const double tolerance_m = 0.030;
  CHECK_FALSE(neighbours.moved(knee, at_m, visible, tolerance_m));  // at its model place
  // 300 mm up the thigh (a ghost or a swap): moved.
  std::vector<Eigen::Vector3d> moved_m = at_m;
  moved_m[knee] += Eigen::Vector3d(0.0, 0.300, 0.0);
  CHECK(neighbours.moved(knee, moved_m, visible, tolerance_m));
  // 10 mm: within the tolerance of every distance.
  moved_m[knee] = at_m[knee] + Eigen::Vector3d(0.0, 0.0, 0.010);
  CHECK_FALSE(neighbours.moved(knee, moved_m, visible, tolerance_m));
  // No neighbour measured: nothing says it stayed.
  std::vector<std::uint8_t> alone(points.size(), 0);
  alone[knee] = 1;
  CHECK(neighbours.moved(knee, at_m, alone, tolerance_m));
}

TEST_CASE("walk1 unswapped: the mirror rule relabels nothing, the joints are as without it",
          "[swap]") {
  if (!have_walk()) return;
  std::vector<std::string> names;
  for (const MarkerTarget& m : walk_config().tracker.markers) names.push_back(m.marker);
  const std::size_t pairs = mirror_pairs_from_names(names).size();
  INFO(pairs << " left/right pairs among " << names.size() << " markers");
  CHECK(pairs >= 10);  // the rule had pairs to judge
  DaemonConfig off = walk_config();
  off.tracker.outliers.relabel_mirrored = false;
  const TrialSolution with = solve_trial(walk_config(), walk());
  const TrialSolution without = solve_trial(off, walk());
  REQUIRE(with.joints.positions_m.size() == without.joints.positions_m.size());
  std::size_t differ = 0;
  for (std::size_t k = 0; k < with.joints.positions_m.size(); ++k)
    differ += !(with.joints.positions_m[k] == without.joints.positions_m[k]);
  CHECK(differ == 0);
}

namespace {

// walk1 with the whole right leg's markers (thigh, shank, foot) exchanged with the left's in
// frames [first, first + 10): the joint centres' worst distance from the unswapped solve over
// frames [check_first, check_end), metres.
double whole_leg_swap_error_m(const DaemonConfig& config, std::size_t first,
                              std::size_t check_first, std::size_t check_end) {
  MarkerTrial swapped = walk();
  for (const std::string part : {"Thigh.Upper", "Thigh.Front", "Thigh.Rear", "Shank.Upper",
                                 "Shank.Front", "Shank.Rear", "Heel", "Midfoot.Sup",
                                 "Midfoot.Lat", "Toe.Tip", "Toe.Lat", "Toe.Med"}) {
    const int r = swapped.find("R." + part), l = swapped.find("L." + part);
    REQUIRE(r >= 0);
    REQUIRE(l >= 0);
    for (std::size_t f = first; f < first + 10; ++f)
      std::swap(swapped.at(f, std::size_t(r)), swapped.at(f, std::size_t(l)));
  }
  const TrialSolution clean = solve_trial(config, walk());
  const TrialSolution s = solve_trial(config, swapped);
  double worst_m = 0.0;
  for (std::size_t f = check_first; f < std::min(check_end, s.joints.frames()); ++f)
    for (std::size_t j = 0; j < s.joints.labels.size(); ++j)
      if (std::isfinite(joint_distance_m(s, clean, f, j)))
        worst_m = std::max(worst_m, joint_distance_m(s, clean, f, j));
  return worst_m;
}

}  // namespace

TEST_CASE("walk1 with a whole leg's markers swapped with the other's for 10 frames: undone",
          "[swap]") {
  if (!have_walk()) return;
  DaemonConfig off = walk_config();
  off.tracker.outliers.relabel_mirrored = false;
  for (const std::size_t first : {std::size_t{40}, std::size_t{70}, std::size_t{100},
                                  std::size_t{140}}) {
    const double on_m = whole_leg_swap_error_m(walk_config(), first, first, first + 10);
    const double off_m = whole_leg_swap_error_m(off, first, first, first + 10);
    INFO("frames " << first << "-" << first + 9 << ": joint centres at most " << on_m * 1e3
                   << " mm from the unswapped solve with the mirror rule, " << off_m * 1e3
                   << " mm without");
    CHECK(on_m < 0.010);
    CHECK(off_m > 0.030);
  }
}

TEST_CASE("walk1 swapped from the first frame: once mirror_max_s is over, the labels stand",
          "[swap]") {
  if (!have_walk()) return;
  // A cold frame has nothing to judge against: frames 0-9 are tracked swapped, and from
  // frame 10 the correct labels look mirrored to the rule for at most mirror_max_s (0.5 s,
  // 30 frames at 60 Hz). After that the skeleton must be back on the labels.
  const DaemonConfig& c = walk_config();
  const auto settle = static_cast<std::size_t>(std::ceil(c.tracker.outliers.mirror_max_s * 60.0));
  const double after_m = whole_leg_swap_error_m(c, 0, 10 + settle + 10, 1000);
  INFO("joint centres from frame " << 10 + settle + 10 << " at most " << after_m * 1e3
                                   << " mm from the unswapped solve");
  CHECK(after_m < 0.010);
}

namespace {

struct JointDrift {
  double mean_m = 0.0, worst_m = 0.0;
};

// The default config's synthetic motion with 1 mm noise: `tested` tracks it with each marker
// hidden at random with probability hide_share in every frame, `reference` every marker;
// how far apart their joint centres are.
JointDrift joint_drift(const DaemonConfig& config, const TrackerSetup& tested,
                       const TrackerSetup& reference, double hide_share, std::uint64_t seed,
                       int frames) {
  const Model& model = *config.tracker.model;
  const std::vector<int> points = marker_points(config);
  SyntheticMotion motion(model, MotionSettings{});
  Posture truth = Posture::rest(model);
  std::vector<Eigen::Vector3d> measured(points.size());
  std::normal_distribution<double> noise_m(0.0, 1e-3);
  std::uniform_real_distribution<double> draw(0.0, 1.0);
  std::mt19937_64 rng(seed);
  const std::vector<std::uint8_t> all(points.size(), 1);
  std::vector<std::uint8_t> visible(points.size());
  Tracker hidden(tested), clean(reference);
  JointDrift drift;
  int count = 0;
  for (int f = 0; f < frames; ++f) {
    const double t_s = f / 100.0;
    motion.posture_at(t_s, truth);
    motion.sample(truth, points, 0.0, measured);
    for (Eigen::Vector3d& p : measured)
      p += Eigen::Vector3d(noise_m(rng), noise_m(rng), noise_m(rng));
    for (std::uint8_t& v : visible) v = draw(rng) >= hide_share ? 1 : 0;
    const TrackResult& h = hidden.track(t_s, measured, visible);
    const TrackResult& c = clean.track(t_s, measured, all);
    for (std::size_t j = 0; j < h.joints_world_m.size(); ++j) {
      const double d_m = (h.joints_world_m[j] - c.joints_world_m[j]).norm();
      drift.mean_m += d_m;
      drift.worst_m = std::max(drift.worst_m, d_m);
      ++count;
    }
  }
  drift.mean_m /= count;
  return drift;
}

}  // namespace

// scripts/dropout-probe as a test: a tenth of the markers hidden at random in every frame
// (the pelvis's too). Three faults made this 8-300 mm on average (docs/robust-tracking.md,
// "Markers that flicker"): a two-point rigid fit turning about its free axis, a hand-over
// holding a pose that went wrong in a one-frame gap, and FABRIK's loop leaving a fit. Here
// the first alone fails (84 mm worst); each has its own test besides (test_solver.cpp,
// test_gap_fill.cpp).
TEST_CASE(
    "Markers hidden at random in every frame leave the joint centres near the unhidden "
    "solve",
    "[gaps][robust]") {
  const DaemonConfig config = default_daemon_config();
  const JointDrift drift = joint_drift(config, config.tracker, config.tracker, 0.1, 5, 600);
  INFO("joint centres off the unhidden solve: mean " << drift.mean_m * 1e3 << " mm, worst "
                                                     << drift.worst_m * 1e3 << " mm");
  CHECK(drift.mean_m < 2e-3);
  CHECK(drift.worst_m < 50e-3);
}

TEST_CASE("Weak anchors with a free root leave the joint centres near the default anchors' solve",
          "[robust][priorities]") {
  // The built-in model's pelvis markers are one level stronger than the rest. With weak
  // anchors, a limb level's pass turns the pelvis; the pelvis level's pass turns it back,
  // and the limbs, riders of that pass, must not turn back with it (they did: 0.2-0.3 m
  // mean, up to 1 m, at anchor_weight 1 or less; 0.9 m worst at 10 with markers flickering).
  // Without anchors (0) a cold frame takes anchors of 1 (cold_solver_options): without them,
  // from rest, this motion's first frame ended 90 mm RMS off and the warm frames followed it
  // for about 0.4 s.
  const DaemonConfig config = default_daemon_config();
  for (const double anchor : {10.0, 1.0, 0.1, 0.0}) {
    for (const double hide_share : {0.0, 0.1}) {
      TrackerSetup weak = config.tracker;
      weak.solver.anchor_weight = anchor;
      const JointDrift drift = joint_drift(config, weak, config.tracker, hide_share, 11, 300);
      INFO("anchor_weight " << anchor << ", " << hide_share * 100 << " % hidden: mean "
                            << drift.mean_m * 1e3 << " mm, worst " << drift.worst_m * 1e3 << " mm");
      CHECK(drift.mean_m < 2e-3);
      CHECK(drift.worst_m < 30e-3);
    }
  }
}
