// Templates and calibration: a synthetic static trial with known joint centres
// is written as TRC, calibrated and checked; bad templates and missing
// markers give their own messages; the real OpenSim static trial gives
// plausible segment lengths (skipped when ../shared/data is absent).
#include <unistd.h>
#include <Eigen/Geometry>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>

#include "calib/calib_template.hpp"
#include "calib/calibrate.hpp"
#include "calib/static_window.hpp"
#include "config/config_error.hpp"
#include "config/daemon_config.hpp"
#include "config/model_loader.hpp"
#include "io/marker_trial.hpp"
#include "solver/posture.hpp"
#include "leg_subject.hpp"

using namespace fabrik;
using namespace fabrik::calib;
using nlohmann::json;
using test::leg_template;
using test::Subject;

namespace {

std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("fabrik_test_calib_" + std::to_string(getpid()) + "_" + name))
      .string();
}

std::string template_error(const json& doc) {
  try {
    load_template(doc, "bad.json");
  } catch (const ConfigError& e) {
    return e.what();
  }
  FAIL("the template loaded but should have been rejected");
  return "";
}
}  // namespace

TEST_CASE("Harrington 2007 hip regression follows its published equations", "[calib]") {
  // PW 250 mm, PD 160 mm: x = -0.24 PD - 9.9, y = -0.30 PW - 10.9, z = +-(0.33 PW + 7.3).
  const Eigen::Vector3d r = hip_centre_in_pelvis_m(HipRegression::harrington2007, true, 0.25, 0.16);
  CHECK(r.x() == Approx(-0.0483));
  CHECK(r.y() == Approx(-0.0859));
  CHECK(r.z() == Approx(0.0898));
  const Eigen::Vector3d l =
      hip_centre_in_pelvis_m(HipRegression::harrington2007, false, 0.25, 0.16);
  CHECK(l.z() == Approx(-0.0898));
  CHECK(l.x() == Approx(r.x()));
}

TEST_CASE("Calibration recovers joint centres from a synthetic static trial", "[calib]") {
  const Subject s;
  const std::string trc = temp_path("static.trc");
  io::write_trc(trc, s.trial(), "mm");
  const io::MarkerTrial trial = io::read_trial(trc);
  std::filesystem::remove(trc);
  const CalibTemplate t = load_template(leg_template(), "leg.json");
  const CalibrationResult r = calibrate(t, trial, "static.trc");

  const double tol = 1e-6;  // TRC keeps 1 nm; the model file 1 um
  auto near = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, double eps) {
    INFO("got " << a.transpose() << ", expected " << b.transpose());
    CHECK((a - b).norm() < eps);
  };
  // Hips: the regression in the (rotated) pelvis frame, computed here from the formula.
  const Eigen::Vector3d hip_r(-0.24 * 160 - 9.9, -0.30 * 250 - 10.9, 0.33 * 250 + 7.3);
  const Eigen::Vector3d hip_l(hip_r.x(), hip_r.y(), -hip_r.z());
  near(r.point_world_m("r_hip"), s.mid_asis_m + s.r_pelvis * hip_r * 1e-3, tol);
  near(r.point_world_m("l_hip"), s.mid_asis_m + s.r_pelvis * hip_l * 1e-3, tol);
  near(r.point_world_m("origin"),
       s.mid_asis_m + s.r_pelvis * Eigen::Vector3d(hip_r.x(), hip_r.y(), 0) * 1e-3, tol);
  // Offset in the pelvis frame built from markers.
  near(r.point_world_m("lumbar"), s.mid_asis_m + s.r_pelvis * Eigen::Vector3d(0, 0.1, 0.02), tol);
  // Midpoints of the static-only medial markers and their lateral partners.
  near(r.point_world_m("r_knee"), Eigen::Vector3d(0.35, 0.50, 0.0), tol);
  near(r.point_world_m("r_ankle"), Eigen::Vector3d(0.33, 0.10, 0.02), tol);
  CHECK(r.lengths.size() == 5);

  // The written model: static-only markers left out, rest markers at the static means.
  const Model m = load_model(json::parse(r.config["model"].dump()), "calibrated");
  CHECK(m.find_point("RKNM") < 0);
  CHECK(m.find_point("RANM") < 0);
  const Posture rest = Posture::rest(m);
  for (const char* name : {"RASI", "LASI", "SACR", "RTHI", "RKNE", "RTIB", "RANK"})
    near(rest.point_world_m(m, m.find_point(name)), s.at(name), 2e-6);
  near(rest.point_world_m(m, m.find_point("r_knee")), r.point_world_m("r_knee"), 2e-6);
  CHECK(r.rest_max_m < 2e-6);
  // The window's frames are the static posture +-0.5 mm: the fit leaves about that.
  CHECK(r.fit_rms_mean_m < 1.5e-3);
  CHECK(r.fits.size() == 7);

  // A complete daemon config, with the template's levels and weights.
  const json c = json::parse(r.config.dump());
  CHECK(c["format"] == "fabrikd-config/1");
  CHECK(c["targets"]["default"]["level"] == 0);
  CHECK(c["targets"]["markers"]["RASI"]["level"] == 2);
  CHECK(c["targets"]["markers"]["SACR"]["weight"] == 2.0);
  CHECK_FALSE(c["targets"]["markers"].contains("RTHI"));
  CHECK(c["solver"]["segment_fit"] == "rigid");
  CHECK(c["solver"]["root"] == "free");
  CHECK(c["solver"]["tolerance_mm"] == 0.1);
  CHECK(c["solver"]["max_iterations"] == 50);
  const DaemonConfig d = load_daemon_config(c.dump(), "calibrated.json");
  CHECK(d.tracker.markers.size() == 7);
}

TEST_CASE("A window of the trial is averaged, frame numbers are the file's", "[calib]") {
  const Subject s;
  io::MarkerTrial trial = s.trial();
  trial.first_frame = 101;
  const CalibTemplate t = load_template(leg_template(), "leg.json");
  CalibrateOptions o;
  o.first_frame = 103;  // frames 2 and 3 of the trial: RTHI missing in both
  o.frames = 2;
  try {
    calibrate(t, trial, "static.trc", o);
    FAIL("calibrated without RTHI");
  } catch (const CalibrationError& e) {
    const std::string what = e.what();
    CHECK_THAT(what, Catch::Contains("'RTHI' (no sample in the window)"));
    CHECK_THAT(what, Catch::Contains("frames 103 to 104"));
  }
  o.first_frame = 105;
  CHECK_NOTHROW(calibrate(t, trial, "static.trc", o));
  o.first_frame = 50;
  CHECK_THROWS_WITH(calibrate(t, trial, "static.trc", o), Catch::Contains("outside the trial"));
}

TEST_CASE("A marker needed only for a joint centre must be in the static trial", "[calib]") {
  const Subject s;
  io::MarkerTrial trial = s.trial();
  trial.labels[5] = "XKNM";  // the medial knee marker is not there
  const CalibTemplate t = load_template(leg_template(), "leg.json");
  CHECK_THROWS_WITH(calibrate(t, trial, "static.trc"),
                    Catch::Contains("'RKNM' (not in the trial)") && Catch::Contains("Fix:"));
  // A lab's own spelling: the closest label is named (it was left to the user to find).
  trial.labels[5] = "R_KNM";
  CHECK_THROWS_WITH(calibrate(t, trial, "static.trc"),
                    Catch::Contains("'RKNM' (not in the trial); closest labels: RKNM ~ R_KNM ("));
  // Subject prefixes as Vicon writes them match.
  trial.labels[5] = "Subject:RKNM";
  const CalibrationResult r = calibrate(t, trial, "static.c3d");
  CHECK(r.notes.size() == 2);  // the prefixed match, and RTHI missing in two frames
}

TEST_CASE("Each kind of bad template has its own clear message", "[calib]") {
  struct Case {
    const char* what;
    std::function<void(json&)> edit;
    const char* pointer;
    const char* text;
  };
  const std::vector<Case> cases = {
      {"wrong format", [](json& t) { t["format"] = "fabrikd-model/1"; }, "at /format",
       "unsupported format"},
      {"unknown key", [](json& t) { t["segments"][1]["markrs"] = json::object(); },
       "at /segments/1/markrs", "did you mean 'markers'"},
      {"base not in parent", [](json& t) { t["segments"][2]["base"] = "r_hip"; },
       "at /segments/2/base", "not a point of segment 'r_thigh'"},
      {"unknown name",
       [](json& t) { t["segments"][1]["points"]["r_knee"]["midpoint"][1] = "RKNX"; },
       "at /segments/1/points/r_knee/midpoint/1", "'RKNX' is neither a point nor a marker"},
      {"cycle", [](json& t) { t["segments"][0]["points"]["lumbar"]["from"] = "lumbar"; },
       "at /segments/0/points/lumbar", "cycle"},
      {"two roots", [](json& t) { t["segments"][2].erase("parent"); }, "at /segments/2",
       "second root"},
      {"parent after child", [](json& t) { t["segments"][1]["parent"] = "r_shank"; },
       "at /segments/1/parent", "not a segment listed before"},
      {"offset without frame", [](json& t) { t["segments"][0].erase("frame"); },
       "at /segments/0/points/lumbar", "needs a frame"},
      {"frame with one axis", [](json& t) { t["segments"][0]["frame"].erase(1); },
       "at /segments/0/frame", "two axes"},
      {"bad side", [](json& t) { t["segments"][0]["points"]["r_hip"]["side"] = "up"; },
       "at /segments/0/points/r_hip/side", "unknown side"},
      {"bad regression",
       [](json& t) { t["segments"][0]["points"]["r_hip"]["regression"] = "davis"; },
       "at /segments/0/points/r_hip/regression", "unknown regression"},
      {"duplicate name",
       [](json& t) {
         t["segments"][1]["points"]["RTIB"] = {{"at", "RTHI"}};
       },
       "at /segments/2/markers/RTIB", "used twice"},
      {"two rules", [](json& t) { t["segments"][1]["points"]["r_knee"]["at"] = "RKNE"; },
       "at /segments/1/points/r_knee", "exactly one rule"},
      {"joint used twice",
       [](json& t) {
         t["segments"][2]["base"] = "r_hip";
         t["segments"][2]["parent"] = "pelvis";
       },
       "at /segments/2/base", "already the base of segment 'r_thigh'"},
  };
  for (const Case& c : cases) {
    SECTION(c.what) {
      json t = leg_template();
      c.edit(t);
      const std::string msg = template_error(t);
      CHECK_THAT(msg, Catch::StartsWith("bad.json: " + std::string(c.pointer) + ":"));
      CHECK_THAT(msg, Catch::Contains(c.text));
      CHECK_THAT(msg, Catch::Contains("Fix:"));
    }
  }
}

TEST_CASE("Shipped templates load", "[calib]") {
  const std::string dir = std::string(FABRIK_SOURCE_DIR) + "/config/templates/";
  const CalibTemplate g = load_template_file(dir + "gait2354.json");
  CHECK(g.segments.size() == 20);  // feet split into hindfoot and forefoot
  int tracked = 0, static_only = 0;
  for (const MarkerDef& m : g.markers) (m.static_only ? static_only : tracked)++;
  CHECK(tracked == 41);  // exactly the markers of subject01_walk1.trc
  CHECK(static_only == 8);
  const CalibTemplate v = load_template_file(dir + "vicon_upper_body.json");
  CHECK(v.markers.size() == 43);
}

TEST_CASE("gait2354 calibrated on subject01_static.trc is anatomically plausible",
          "[calib][data]") {
  const std::string path = std::string(FABRIK_SHARED_DATA_DIR) + "/subject01_static.trc";
  if (!std::filesystem::exists(path)) {
    WARN("SKIPPED: " << path << " is absent (real data lives in ../shared/data)");
    return;
  }
  const CalibTemplate t =
      load_template_file(std::string(FABRIK_SOURCE_DIR) + "/config/templates/gait2354.json");
  const CalibrationResult r = calibrate(t, io::read_trial(path), path);
  auto length = [&](const std::string& seg) {
    for (const SegmentLength& l : r.lengths)
      if (l.segment == seg) return l.length_m;
    FAIL("no length for " << seg);
    return 0.0;
  };
  for (const char* s : {"r_thigh", "l_thigh"}) {
    INFO(s);
    CHECK(length(s) > 0.35);
    CHECK(length(s) < 0.50);
  }
  for (const char* s : {"r_shank", "l_shank"}) {
    INFO(s);
    CHECK(length(s) > 0.33);
    CHECK(length(s) < 0.48);
  }
  for (const char* s : {"r_humerus", "l_humerus", "r_forearm", "l_forearm"}) {
    INFO(s);
    CHECK(length(s) > 0.20);
    CHECK(length(s) < 0.36);
  }
  const double hip_width = (r.point_world_m("r_hip") - r.point_world_m("l_hip")).norm();
  CHECK(hip_width > 0.14);
  CHECK(hip_width < 0.24);
  CHECK(r.rest_max_m < 1e-5);
  CHECK(r.fit_rms_mean_m < 3e-3);  // a static trial: marker noise and a little sway
  const Model m = load_model(json::parse(r.config["model"].dump()), "subject01");
  CHECK(m.marker_points().size() == 41);
}

TEST_CASE("calibrate reports how much the subject moved in the window, --auto-window picks the "
          "stillest",
          "[calib]") {
  const std::string path = FABRIK_SHARED_DATA_DIR "/subject01_static.trc";
  if (!std::filesystem::exists(path)) {
    WARN("skipped: " << path << " not found");
    return;
  }
  const calib::CalibTemplate tmpl =
      calib::load_template_file(FABRIK_SOURCE_DIR "/config/templates/gait2354.json");
  io::MarkerTrial trial = io::read_trial(path);
  // The subject steps 10 mm forward at frame 100: a window across it moved about 5 mm.
  for (std::size_t f = 100; f < trial.frames(); ++f)
    for (std::size_t m = 0; m < trial.markers(); ++m) trial.at(f, m).x() += 0.010;
  const auto has_motion_note = [](const calib::CalibrationResult& r) {
    for (const std::string& n : r.notes)
      if (n.find("moved in the static window") != std::string::npos) return true;
    return false;
  };
  const calib::CalibrationResult across =
      calib::calibrate(tmpl, trial, "s.trc", {.first_frame = 91, .frames = 20});
  CHECK(across.window_motion_m >= 0.0049);
  CHECK(has_motion_note(across));
  CHECK_THAT(calib::calibration_report(across), Catch::Contains("motion in it"));
  const calib::CalibrationResult still =
      calib::calibrate(tmpl, trial, "s.trc", {.auto_window = 20});
  CHECK(still.frames == 20);
  CHECK(still.window_motion_m < calib::kStillWindowWarn_m);
  CHECK_FALSE(has_motion_note(still));
  // No window of 20 frames is stiller than the chosen one.
  for (long long first = 1; first + 19 <= static_cast<long long>(trial.frames()); first += 7)
    CHECK(calib::calibrate(tmpl, trial, "s.trc", {.first_frame = first, .frames = 20})
              .window_motion_m >= still.window_motion_m - 1e-12);
  CHECK_THROWS_WITH(calib::calibrate(tmpl, trial, "s.trc", {.frames = 20, .auto_window = 20}),
                    Catch::Contains("--auto-window"));
}

TEST_CASE("A template beyond the model's limits is refused as it is read, with the pointer",
          "[calib][limits]") {
  SECTION("segments") {
    json t = leg_template();
    for (int s = 0; s < ModelLimits::kSegments; ++s)
      t["segments"].push_back({{"name", "x" + std::to_string(s)}, {"parent", "pelvis"},
                               {"base", "lumbar"}});
    CHECK_THAT(template_error(t), Catch::Contains("at /segments/512:") &&
                                      Catch::Contains("fabrikd takes at most 512"));
  }
  SECTION("depth") {
    json t = leg_template();
    std::string parent = "r_shank";  // 3 deep
    for (int s = 0; s < ModelLimits::kDepth; ++s) {
      const std::string name = "c" + std::to_string(s);
      t["segments"].push_back({{"name", name}, {"parent", parent}, {"base", "r_ankle"}});
      parent = name;
    }
    CHECK_THAT(
        template_error(t),
        Catch::Contains("at /segments/64/parent:") &&
            Catch::Contains("ends a chain of more than 64 segments from the root (both counted)"));
  }
  SECTION("markers on one segment, and in the template") {
    json t = leg_template();
    for (int k = 0; k < ModelLimits::kPointsPerSegment; ++k)
      t["segments"][2]["markers"]["M" + std::to_string(k)] = json::object();
    CHECK_THAT(template_error(t), Catch::Contains("at /segments/2:") &&
                                      Catch::Contains("fabrikd takes at most 256"));
    json u = leg_template();
    for (int s = 0; s < 5; ++s) {
      json seg = {{"name", "x" + std::to_string(s)}, {"parent", "pelvis"}, {"base", "lumbar"}};
      for (int k = 0; k < 250; ++k)
        seg["markers"]["M" + std::to_string(s) + "_" + std::to_string(k)] = json::object();
      u["segments"].push_back(seg);
    }
    CHECK_THAT(template_error(u), Catch::Contains("more than 1024 markers"));
  }
}
