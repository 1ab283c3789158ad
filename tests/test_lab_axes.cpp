// Coordinates relative to the lab: the same numbers whichever way the lab's
// axes point (declared, or detected from the static trial), and continuous
// over frames (never wrapping at +-180 deg). Turned copies of a synthetic
// subject always; of subject01 when ../shared/data is there (skipped else).
#include <Eigen/Geometry>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <numbers>

#include "calib/calibrate.hpp"
#include "config/config_error.hpp"
#include "config/daemon_config.hpp"
#include "config/model_loader.hpp"
#include "io/opensim_table.hpp"
#include "leg_subject.hpp"
#include "mot_steps.hpp"
#include "offline/solve_trial.hpp"
#include "solver/joint_angles.hpp"
#include "solver/model_builder.hpp"
#include "temp_file.hpp"
#include "tools/synth.hpp"
#include "tracking/tracker.hpp"

using namespace fabrik;
using nlohmann::json;

namespace {

constexpr double kDeg = 180.0 / std::numbers::pi;

// Exact turns of the lab (whole-number matrices: the copies are exact).
// A Z-up lab: +90 deg about x, y -> z, z -> -y (Vicon Nexus, QTM).
Eigen::Matrix3d z_up_from_y_up() {
  Eigen::Matrix3d r;
  r << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  return r;
}
// Z up and the walk along +y: x -> y, y -> z, z -> x (120 deg about (1, 1, 1)).
Eigen::Matrix3d z_up_y_forward_from_y_up() {
  Eigen::Matrix3d r;
  r << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  return r;
}

io::MarkerTrial turned(io::MarkerTrial trial, const Eigen::Matrix3d& r_new_old) {
  for (Eigen::Vector3d& p : trial.positions_m)
    if (p.allFinite()) p = r_new_old * p;
  return trial;
}

// Through a TRC file in a temp dir, as a user's copy would be.
io::MarkerTrial through_file(const io::MarkerTrial& trial) {
  test::TempFile trc(".trc");
  io::write_trc(trc.path(), trial, "mm");
  return io::read_trial(trc.path());
}

// The leg subject's template with segment frames and OpenSim-style
// coordinates: the pelvis relative to the lab, the hip and the knee.
json leg_template_with_coordinates() {
  json t = test::leg_template();
  t["segments"][1]["frame"] = json::parse(
      R"([{"axis": "y", "from": "r_knee", "to": "r_hip"}, {"axis": "z", "from": "RKNM", "to": "RKNE"}])");
  t["segments"][2]["frame"] = json::parse(
      R"([{"axis": "y", "from": "r_ankle", "to": "r_knee"}, {"axis": "z", "from": "RANM", "to": "RANK"}])");
  t["coordinates"] = json::parse(R"({
    "pelvis_tilt": {"segment": "pelvis", "relative_to": "world", "axis": "z"},
    "pelvis_list": {"segment": "pelvis", "relative_to": "world", "axis": "x"},
    "pelvis_rotation": {"segment": "pelvis", "relative_to": "world", "axis": "y"},
    "pelvis_tx": {"point": "origin", "axis": "x"},
    "pelvis_ty": {"point": "origin", "axis": "y"},
    "pelvis_tz": {"point": "origin", "axis": "z"},
    "hip_flexion_r": {"segment": "r_thigh", "axis": "z"},
    "hip_adduction_r": {"segment": "r_thigh", "axis": "x"},
    "hip_rotation_r": {"segment": "r_thigh", "axis": "y"},
    "knee_angle_r": {"segment": "r_shank", "axis": "z", "sign": -1}})");
  return t;
}

calib::CalibrationResult calibrated(const json& tmpl, const io::MarkerTrial& stat,
                                    const calib::CalibrateOptions& options = {}) {
  return calib::calibrate(calib::load_template(tmpl, "leg.json"), stat, "static.trc", options);
}
DaemonConfig config_of(const calib::CalibrationResult& r) {
  return load_daemon_config(r.config.dump(), "calibrated.json");
}

// 2 s at 100 Hz of the calibrated Y-up subject moving (free joints, the root
// travelling and turning), every marker seen, no noise.
io::MarkerTrial leg_motion(const DaemonConfig& config) {
  tools::SynthSetup setup;
  setup.model = config.tracker.model;
  for (const MarkerTarget& m : config.tracker.markers) {
    setup.marker_names.push_back(m.marker);
    setup.marker_points.push_back(m.point);
  }
  tools::SynthOptions o;
  o.seconds = 2.0;
  o.noise_mm = 0.0;
  return tools::make_synth_trial(setup, o).markers;
}

struct Difference {
  double rotation_deg = 0.0, translation_mm = 0.0;
  std::string rotation_worst, translation_worst;
};

// Largest difference per kind between two runs of the same coordinates.
Difference difference(const TrialSolution& a, const TrialSolution& b) {
  REQUIRE(a.coordinate_names == b.coordinate_names);
  REQUIRE(a.coordinates.size() == b.coordinates.size());
  const std::size_t n = a.coordinate_names.size();
  Difference d;
  for (std::size_t k = 0; k < a.coordinates.size(); ++k) {
    const std::size_t c = k % n;
    const double diff = std::abs(a.coordinates[k] - b.coordinates[k]);
    if (a.coordinate_is_rotation[c] && diff * kDeg > d.rotation_deg)
      d.rotation_deg = diff * kDeg, d.rotation_worst = a.coordinate_names[c];
    if (!a.coordinate_is_rotation[c] && diff * 1e3 > d.translation_mm)
      d.translation_mm = diff * 1e3, d.translation_worst = a.coordinate_names[c];
  }
  return d;
}

void check_same(const TrialSolution& a, const TrialSolution& b) {
  const Difference d = difference(a, b);
  INFO("largest differences: " << d.rotation_deg << " deg (" << d.rotation_worst << "), "
                               << d.translation_mm << " mm (" << d.translation_worst << ")");
  CHECK(d.rotation_deg <= 0.1);
  CHECK(d.translation_mm <= 0.1);
}

// The run's .mot, written and read back, steps no more than `bound_deg`
// between rows (the issue's 10 deg by default).
void check_mot_continuous(const TrialSolution& s, double bound_deg = test::kMaxCoordinateStepDeg) {
  test::TempFile mot(".mot");
  io::write_opensim_table(mot.path(), angles_table(s));
  const io::OpenSimTable table = io::read_opensim_table(mot.path());
  const test::TableStep step = test::largest_step(table), jump = test::largest_jump(table);
  INFO("largest step " << step.step << " (" << step.column << " at " << step.time_s
                       << " s), largest jump " << jump.step << " (" << jump.column << " at "
                       << jump.time_s << " s)");
  CHECK(jump.step <= bound_deg);
}

double value_at(const TrialSolution& s, const std::string& name, std::size_t frame) {
  const std::size_t n = s.coordinate_names.size();
  const auto it = std::find(s.coordinate_names.begin(), s.coordinate_names.end(), name);
  REQUIRE(it != s.coordinate_names.end());
  return s.coordinates[frame * n + static_cast<std::size_t>(it - s.coordinate_names.begin())];
}

}  // namespace

TEST_CASE(
    "Lab axes: a Z-up copy of a synthetic subject gives the Y-up coordinates, detected "
    "from its static trial",
    "[lab_axes][calib]") {
  const json tmpl = leg_template_with_coordinates();
  const io::MarkerTrial static_y = test::Subject().trial();
  const calib::CalibrationResult ry = calibrated(tmpl, static_y);
  CHECK(ry.lab_axes == LabAxes{});  // a Y-up lab keeps today's numbers
  CHECK(ry.model["lab_axes"].dump() == R"({"up":"+y","forward":"+x"})");
  const DaemonConfig cy = config_of(ry);
  const io::MarkerTrial motion_y = leg_motion(cy);
  const TrialSolution sy = solve_trial(cy, motion_y);

  const Eigen::Matrix3d r = z_up_from_y_up();
  const calib::CalibrationResult rz = calibrated(tmpl, through_file(turned(static_y, r)));
  CHECK(rz.lab_axes.up_lab == Eigen::Vector3d::UnitZ());
  CHECK(rz.lab_axes.forward_lab == Eigen::Vector3d::UnitX());
  CHECK(rz.model["lab_axes"].dump() == R"({"up":"+z","forward":"+x"})");
  CHECK_THAT(rz.lab_axes_how, Catch::StartsWith("detected from the static trial"));
  CHECK_THAT(calib::calibration_report(rz), Catch::Contains("Lab axes: up +z, forward +x"));
  const DaemonConfig cz = config_of(rz);
  CHECK(cz.tracker.model->lab_axes == rz.lab_axes);  // the config records them
  const TrialSolution sz = solve_trial(cz, through_file(turned(motion_y, r)));
  check_same(sy, sz);
  // The pelvis really turns and tilts here: the agreement is not of zeros.
  CHECK(std::abs(value_at(sy, "pelvis_rotation", 100)) > 0.3);
  CHECK(std::abs(value_at(sy, "pelvis_tilt", 0)) > 0.1);
  check_mot_continuous(sz);

  // The same Z-up copy taken as Y-up (declared wrongly): the pelvis list
  // sits near 90 deg, as in a Z-up lab without lab axes, and the
  // calibration says the declared up is not the subject's.
  calib::CalibrateOptions y_up;
  y_up.lab_axes = LabAxesSpec{Eigen::Vector3d::UnitY(), std::nullopt};
  const calib::CalibrationResult wrong = calibrated(tmpl, turned(static_y, r), y_up);
  REQUIRE_FALSE(wrong.notes.empty());
  CHECK_THAT(wrong.notes.back(), Catch::StartsWith("the declared lab up axis +y is "));
  CHECK_THAT(wrong.notes.back(), Catch::Contains("which is nearest +z"));
  const TrialSolution sw = solve_trial(config_of(wrong), turned(motion_y, r));
  CHECK(std::abs(std::abs(value_at(sw, "pelvis_list", 0) * kDeg) - 90.0) < 20.0);
}

TEST_CASE(
    "Lab axes: Z up with the walk along +y gives the same coordinates when declared, in "
    "the template or on the command line",
    "[lab_axes][calib]") {
  const json tmpl = leg_template_with_coordinates();
  const io::MarkerTrial static_y = test::Subject().trial();
  const DaemonConfig cy = config_of(calibrated(tmpl, static_y));
  const io::MarkerTrial motion_y = leg_motion(cy);
  const TrialSolution sy = solve_trial(cy, motion_y);
  const Eigen::Matrix3d r = z_up_y_forward_from_y_up();
  const io::MarkerTrial static_c = turned(static_y, r), motion_c = turned(motion_y, r);

  SECTION("in the template") {
    json declared = tmpl;
    declared["lab_axes"] = {{"up", "+z"}, {"forward", "+y"}};
    const calib::CalibrationResult rc = calibrated(declared, static_c);
    CHECK(rc.lab_axes_how == "declared in the template");
    CHECK(rc.model["lab_axes"].dump() == R"({"up":"+z","forward":"+y"})");
    check_same(sy, solve_trial(config_of(rc), motion_c));
  }
  SECTION("on the command line, over the template's") {
    json declared = tmpl;
    declared["lab_axes"] = {{"up", "+y"}};
    calib::CalibrateOptions o;
    o.lab_axes = LabAxesSpec{Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitY()};
    const calib::CalibrationResult rc = calibrated(declared, static_c, o);
    CHECK(rc.lab_axes_how == "declared with --lab-up/--lab-forward");
    check_same(sy, solve_trial(config_of(rc), motion_c));
  }
  SECTION("detected: up is found, forward stays +x and the calibration says the subject faces +y") {
    const calib::CalibrationResult rc = calibrated(tmpl, static_c);
    CHECK(rc.lab_axes.up_lab == Eigen::Vector3d::UnitZ());
    CHECK(rc.lab_axes.forward_lab == Eigen::Vector3d::UnitX());
    bool said = false;
    for (const std::string& n : rc.notes)
      said = said || n.find("the subject faces +y in the static trial") != std::string::npos;
    CHECK(said);
  }
}

TEST_CASE("Lab axes: up along x takes forward from the pelvis's front", "[lab_axes][calib]") {
  // x up: y -> x, x -> -y (z stays); the subject faces -y.
  Eigen::Matrix3d r;
  r << 0, 1, 0, -1, 0, 0, 0, 0, 1;
  const json tmpl = leg_template_with_coordinates();
  const io::MarkerTrial static_y = test::Subject().trial();
  const DaemonConfig cy = config_of(calibrated(tmpl, static_y));
  const io::MarkerTrial motion_y = leg_motion(cy);
  const calib::CalibrationResult rx = calibrated(tmpl, turned(static_y, r));
  CHECK(rx.lab_axes.up_lab == Eigen::Vector3d::UnitX());
  CHECK(rx.lab_axes.forward_lab == -Eigen::Vector3d::UnitY());
  check_same(solve_trial(cy, motion_y), solve_trial(config_of(rx), turned(motion_y, r)));
}

TEST_CASE("Lab axes in a model file: read, checked, with messages that say the fix",
          "[lab_axes][config]") {
  json model = json::parse(R"({
    "format": "fabrikd-model/1", "units": "m",
    "segments": [{"name": "body", "base": "root", "markers": {"a": [0, 1, 0]}}]})");
  CHECK(load_model(model, "m.json").lab_axes == LabAxes{});
  model["lab_axes"] = {{"up", "z"}};
  const Model z = load_model(model, "m.json");
  CHECK(z.lab_axes.up_lab == Eigen::Vector3d::UnitZ());
  CHECK(z.lab_axes.forward_lab == Eigen::Vector3d::UnitX());  // x is horizontal: kept
  auto error = [&](const json& axes) {
    json m = model;
    m["lab_axes"] = axes;
    try {
      load_model(m, "m.json");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("loaded");
  };
  CHECK_THAT(error({{"up", "q"}}), Catch::Contains("at /lab_axes/up: 'q' is not an axis"));
  CHECK_THAT(error({{"up", "+z"}, {"forward", "-z"}}),
             Catch::Contains("at /lab_axes/forward: forward is along the up axis"));
  CHECK_THAT(error({{"up", "-x"}}),
             Catch::Contains("with x up, the lab's forward axis is not clear"));
  CHECK_THAT(error({{"up", "+z"}, {"foward", "+x"}}), Catch::Contains("did you mean 'forward'"));
}

namespace {

// One rigid body with three markers and its heading as a coordinate.
struct Turntable {
  std::shared_ptr<const Model> model;
  TrackerSetup setup;
  Turntable() {
    SegmentSpec body;
    body.name = "body";
    body.base = "root";
    body.points = {
        {"a", {0.2, 0.0, 0.0}, true}, {"b", {0.0, 0.3, 0.0}, true}, {"c", {0.0, 0.0, 0.25}, true}};
    CoordinateSpec heading;
    heading.name = "heading";
    heading.segment = "body";
    heading.axis = 1;  // y: the Cardan angle about the vertical
    model = std::make_shared<const Model>(
        build_model("turntable", {body}, Eigen::Vector3d(0, 1, 0), {heading}));
    setup.model = model;
    for (int p : model->marker_points())
      setup.markers.push_back({model->points[p].name, p, 0, 1.0});
    setup.solver.root = RootMode::free;
    setup.solver.segment_fit = SegmentFit::rigid;
  }
  // The markers with the body turned by `angle_rad` about the vertical.
  std::vector<Eigen::Vector3d> at(double angle_rad) const {
    std::vector<Eigen::Vector3d> out;
    const Eigen::Matrix3d r =
        Eigen::AngleAxisd(angle_rad, Eigen::Vector3d::UnitY()).toRotationMatrix();
    for (const MarkerTarget& m : setup.markers)
      out.push_back(model->root_rest_m + r * model->points[m.point].p_local_m);
    return out;
  }
};

}  // namespace

TEST_CASE("A heading turning through +-180 deg is continuous, from the first frame on",
          "[lab_axes][tracker]") {
  const Turntable t;
  Tracker tracker(t.setup);
  const std::vector<std::uint8_t> visible(3, 1);
  // From 170 deg, two turns and a bit at 5 deg a frame, 100 Hz.
  double previous = NAN, largest_step_deg = 0.0;
  const int frames = 160;
  for (int f = 0; f < frames; ++f) {
    const double truth = (170.0 + 5.0 * f) / kDeg;
    const double value = tracker.track(f * 0.01, t.at(truth), visible).coordinates[0];
    INFO("frame " << f << ": " << value * kDeg << " deg, truth " << truth * kDeg);
    CHECK(std::abs(value - truth) * kDeg < 0.1);  // not wrapped: the truth itself
    if (f > 0) largest_step_deg = std::max(largest_step_deg, std::abs(value - previous) * kDeg);
    previous = value;
  }
  CHECK(largest_step_deg == Approx(5.0).margin(0.1));
  // A gap long enough for a cold start: the same recording, still continuous.
  const double after_gap =
      tracker.track(frames * 0.01 + 2.0, t.at(previous + 0.05), visible).coordinates[0];
  CHECK(after_gap == Approx(previous + 0.05).margin(0.1 / kDeg));
  // A clock that goes back is a new recording: principal values again.
  const double restarted = tracker.track(0.0, t.at(previous), visible).coordinates[0];
  CHECK(std::abs(restarted) <= std::numbers::pi + 1e-12);
  CHECK(restarted == Approx(std::remainder(previous, 2 * std::numbers::pi)).margin(0.1 / kDeg));
  // So does reset().
  tracker.track(0.01, t.at(previous + 0.05), visible);
  tracker.reset();
  CHECK(std::abs(tracker.track(0.02, t.at(previous + 0.1), visible).coordinates[0]) <=
        std::numbers::pi + 1e-12);
}

TEST_CASE(
    "Flips of about 180 deg back and forth do not walk a heading off by whole turns, and a jump "
    "that lasts half a second is kept",
    "[lab_axes][tracker]") {
  const Turntable t;
  Tracker tracker(t.setup);
  const std::vector<std::uint8_t> visible(3, 1);
  // A left/right swap turns the body about 180 deg for a frame: the reviewer's keypoint trial
  // read -19, -197, -34, -213, then -28 (principal values), and -388 was written for -28.
  const std::vector<double> seen_deg{-19, -197, -34, -213, -28, -29, -30};
  const std::vector<bool> flipped{false, true, false, true, false, false, false};
  double t_s = 0.0, last_unflipped_deg = NAN;
  for (std::size_t f = 0; f < seen_deg.size(); ++f, t_s += 0.01) {
    const double value_deg =
        tracker.track(t_s, t.at(seen_deg[f] / kDeg), visible).coordinates[0] * kDeg;
    INFO("frame " << f << ": seen " << seen_deg[f] << ", written " << value_deg);
    if (!flipped[f]) {
      CHECK(value_deg == Approx(seen_deg[f]).margin(0.1));  // the truth itself
      last_unflipped_deg = value_deg;
    } else {  // a whole-turn equivalent of what was seen, within half a turn of the heading
      CHECK(std::abs(std::remainder(value_deg - seen_deg[f], 360.0)) < 0.1);
      CHECK(std::abs(value_deg - last_unflipped_deg) <= 180.0);
    }
  }
  // A jump that then goes on moving (a turn while the markers were away): written on from the
  // frame before, through +180 without a whole-turn step, and kept as the branch after 0.5 s.
  double value_deg = NAN, previous_deg = -28.0, largest_step_deg = 0.0;
  const double jumped_deg = -28 + 150;
  for (int f = 0; f < 180; ++f, t_s += 0.01) {
    value_deg =
        tracker.track(t_s, t.at((jumped_deg + 1.0 * f) / kDeg), visible).coordinates[0] * kDeg;
    if (f > 0) largest_step_deg = std::max(largest_step_deg, std::abs(value_deg - previous_deg));
    previous_deg = value_deg;
  }
  CHECK(value_deg == Approx(jumped_deg + 179).margin(0.1));  // 301, not -59
  CHECK(largest_step_deg == Approx(1.0).margin(0.05));
}

TEST_CASE("Fast real turns at low frame rates are written as turns, not held as swaps",
          "[lab_axes][tracker]") {
  const Turntable t;
  const std::vector<std::uint8_t> visible(3, 1);
  // 1000 deg/s at 10 Hz (100 deg a frame), 600 deg/s at 5 Hz, 640 at 4 Hz (160 deg a frame:
  // no swap can be told from that), 200 deg/s at 2 Hz.
  for (const auto& [rate_hz, deg_per_s] : {std::pair{10.0, 1000.0}, std::pair{5.0, 600.0},
                                           std::pair{4.0, 640.0}, std::pair{2.0, 200.0}}) {
    CAPTURE(rate_hz, deg_per_s);
    Tracker tracker(t.setup);
    for (int f = 0; f < 12; ++f) {
      const double truth_deg = 10.0 + deg_per_s / rate_hz * f;
      const double value_deg =
          tracker.track(f / rate_hz, t.at(truth_deg / kDeg), visible).coordinates[0] * kDeg;
      INFO("frame " << f);
      CHECK(value_deg == Approx(truth_deg).margin(0.1));
    }
  }
}

TEST_CASE("unwrap_coordinates moves rotations by whole turns of their sign, never translations",
          "[lab_axes][angles]") {
  SegmentSpec body;
  body.name = "body";
  body.base = "root";
  body.points = {{"a", {0.2, 0.0, 0.0}, true}};
  CoordinateSpec plain, negative, moved;
  plain.name = "plain";
  plain.segment = "body";
  negative = plain;
  negative.name = "negative";
  negative.sign = -1.0;
  moved.name = "x";
  moved.kind = CoordinateKind::translation;
  moved.point = "a";
  const Model m = build_model("m", {body}, Eigen::Vector3d::Zero(), {plain, negative, moved});
  const double turn = 2 * std::numbers::pi;
  const std::vector<double> previous{3.1, -3.1, 10.0};
  std::vector<double> now{-3.1, 3.1, -10.0};
  unwrap_coordinates(m, previous, now);
  CHECK(now[0] == Approx(turn - 3.1));
  CHECK(now[1] == Approx(3.1 - turn));
  CHECK(now[2] == -10.0);
}

namespace {

struct Subject01 {
  bool present = false;
  std::string static_path, walk_path;
  Subject01() {
    const std::string dir = FABRIK_SHARED_DATA_DIR;
    static_path = dir + "/subject01_static.trc";
    walk_path = dir + "/subject01_walk1.trc";
    present = std::filesystem::exists(static_path) && std::filesystem::exists(walk_path);
    if (!present)
      WARN("SKIPPED: " << static_path << " or " << walk_path
                       << " is absent (real data lives in ../shared/data)");
  }
};

DaemonConfig gait2354(const io::MarkerTrial& stat, const calib::CalibrateOptions& o = {},
                      calib::CalibrationResult* result = nullptr) {
  const calib::CalibTemplate t =
      calib::load_template_file(std::string(FABRIK_SOURCE_DIR) + "/config/templates/gait2354.json");
  calib::CalibrationResult r = calib::calibrate(t, stat, "static.trc", o);
  if (result) *result = r;
  return config_of(r);
}

}  // namespace

TEST_CASE(
    "subject01 in a Z-up lab: every coordinate within 0.1 deg and 0.1 mm of the Y-up "
    "lab's (skipped without ../shared/data)",
    "[lab_axes][data]") {
  const Subject01 data;
  if (!data.present) return;
  const io::MarkerTrial static_y = io::read_trial(data.static_path);
  const io::MarkerTrial walk_y = io::read_trial(data.walk_path);
  const TrialSolution sy = solve_trial(gait2354(static_y), walk_y);
  check_mot_continuous(sy);

  SECTION("Z up, detected") {
    const Eigen::Matrix3d r = z_up_from_y_up();
    calib::CalibrationResult rz;
    const DaemonConfig cz = gait2354(through_file(turned(static_y, r)), {}, &rz);
    CHECK(rz.lab_axes.up_lab == Eigen::Vector3d::UnitZ());
    CHECK(rz.lab_axes.forward_lab == Eigen::Vector3d::UnitX());
    const TrialSolution sz = solve_trial(cz, through_file(turned(walk_y, r)));
    check_same(sy, sz);
    check_mot_continuous(sz);
  }
  SECTION("Z up, walking along +y, declared") {
    const Eigen::Matrix3d r = z_up_y_forward_from_y_up();
    calib::CalibrateOptions o;
    o.lab_axes = LabAxesSpec{Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitY()};
    const TrialSolution sc = solve_trial(gait2354(through_file(turned(static_y, r)), o),
                                         through_file(turned(walk_y, r)));
    check_same(sy, sc);
    check_mot_continuous(sc);
  }
}

// The issue's must-show: no coordinate jumps more than 10 deg between frames
// in any .mot the tests write (largest_jump: a wrap or a snap to a bound, not
// a fast movement; mtp_angle_l swings 43.6 to 0.1 deg in five frames at
// toe-off at 2.0 s, 11.2 deg in its fastest frame at 60 Hz, and passes).
TEST_CASE("walk1's .mot jumps at most 10 deg between frames (skipped without ../shared/data)",
          "[lab_axes][data]") {
  const Subject01 data;
  if (!data.present) return;
  check_mot_continuous(
      solve_trial(gait2354(io::read_trial(data.static_path)), io::read_trial(data.walk_path)));
}

TEST_CASE("largest_jump: a wrap and a lone snap are jumps, a fast sustained swing is not",
          "[lab_axes][numbers]") {
  io::OpenSimTable t;
  t.columns = {"time", "swing", "snap"};
  // swing: 0, 11, 22, 33, 33 (three 11 deg steps in a row); snap: 0, 0, 12, 12, 372 (a
  // lone 12 deg step, then a 360 deg wrap).
  const double swing[] = {0, 11, 22, 33, 33}, snap[] = {0, 0, 12, 12, 372};
  t.rows = 5;
  for (std::size_t r = 0; r < t.rows; ++r) {
    t.time_s.push_back(0.01 * static_cast<double>(r));
    t.values.push_back(swing[r]);
    t.values.push_back(snap[r]);
  }
  const test::TableStep step = test::largest_step(t), jump = test::largest_jump(t);
  CHECK(step.step == Approx(360.0));
  CHECK(jump.step == Approx(360.0));
  CHECK(jump.column == "snap");
  t.values[4 * 2 + 1] = 12.0;  // no wrap: the lone 12 deg step is the largest jump
  CHECK(test::largest_jump(t).step == Approx(12.0));
  CHECK(test::largest_jump(t).time_s == Approx(0.02));
  for (std::size_t r = 0; r < t.rows; ++r)
    t.values[r * 2 + 1] = 0.0;  // snap flat: the swing's
                                // steps sustain each other
  CHECK(test::largest_jump(t).step == 0.0);
  CHECK(test::largest_step(t).step == Approx(11.0));
}
