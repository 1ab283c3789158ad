// Markerless keypoints (docs/keypoints.md): keypoint templates load, calibrate from any
// movement (lengths and their spread), track a rendered trial, and the generator of
// markerless trials is deterministic and injects exactly what it reports.
#include <catch2/catch.hpp>
#include <cmath>
#include <nlohmann/json.hpp>
#include <set>

#include "calib/calib_template.hpp"
#include "calib/keypoint_calibration.hpp"
#include "config/config_error.hpp"
#include "config/daemon_config.hpp"
#include "eval/markerless.hpp"
#include "synth/random_draws.hpp"
#include "tools/synth.hpp"

using namespace fabrik;
using namespace fabrik::calib;

namespace {

std::string template_path(const std::string& name) {
  return std::string(FABRIK_SOURCE_DIR) + "/config/templates/" + name + ".json";
}

// The template's truth model (nominal lengths) as `fabrik synth --config` loads it.
tools::SynthSetup truth_setup(const CalibTemplate& t) {
  const KeypointCalibration k = nominal_keypoint_model(t);
  return tools::synth_setup(load_daemon_config(k.result.config.dump(), "<truth>"));
}

tools::SynthOptions short_trial() {
  tools::SynthOptions o;
  o.seconds = 6.0;
  o.rate_hz = 60.0;
  o.seed = 7;
  return o;
}

double nominal_m(const CalibTemplate& t, const std::string& point) {
  return t.points[static_cast<std::size_t>(t.find_point(point))].rest_m.norm();
}

const KeypointLength& length_of(const KeypointCalibration& k, const std::string& point) {
  for (const KeypointLength& l : k.lengths)
    if (l.point == point) return l;
  FAIL("no length for " << point);
  throw std::logic_error("unreachable");
}

bool same(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return (a.array().isNaN() == b.array().isNaN()).all() &&
         (a.array().isNaN() || a.array() == b.array()).all();
}

}  // namespace

TEST_CASE("exact keypoints of any movement give the template's lengths", "[keypoints]") {
  const CalibTemplate t = load_template_file(template_path("halpe26"));
  const tools::KeypointTrial trial = tools::make_keypoint_trial(truth_setup(t), short_trial(), {});
  const KeypointCalibration k = calibrate_keypoints(t, trial.keypoints, "exact");
  REQUIRE(k.lengths.size() >= 20);
  for (const KeypointLength& l : k.lengths) {
    INFO(l.point << " from " << l.from << ": " << l.median_m * 1e3 << " mm");
    // The neck is measured from the hip centres across the lumbar joint, which moves.
    CHECK(std::abs(l.median_m - nominal_m(t, l.point)) < (l.point == "neck" ? 2e-3 : 0.5e-3));
    CHECK_FALSE(l.wide);
  }
  // The calibrated config tracks its own window to well under a millimetre.
  CHECK(k.result.fit_rms_mean_m < 1e-3);
}

TEST_CASE("a declared up axis far from the keypoints' vertical is noted, a right one is not",
          "[keypoints][lab_axes]") {
  const CalibTemplate t = load_template_file(template_path("halpe26"));
  const tools::KeypointTrial trial = tools::make_keypoint_trial(truth_setup(t), short_trial(), {});
  const auto up_notes = [&](const Eigen::Vector3d& up) {
    KeypointCalibrateOptions o;
    o.lab_axes = LabAxesSpec{up, Eigen::Vector3d::UnitX()};
    std::vector<std::string> found;
    for (const std::string& n : calibrate_keypoints(t, trial.keypoints, "y-up", o).result.notes)
      if (n.find("declared lab up axis") != std::string::npos) found.push_back(n);
    return found;
  };
  CHECK(up_notes(Eigen::Vector3d::UnitY()).empty());  // the trial's own: Y up
  const std::vector<std::string> z = up_notes(Eigen::Vector3d::UnitZ());
  REQUIRE(z.size() == 1);
  CHECK_THAT(z[0],
             Catch::StartsWith("the declared lab up axis +z is 9") &&
                 Catch::Contains("deg from the movement's superior direction") &&
                 Catch::Contains("which is nearest +y. Fix: check the lab axes you declared"));
}

TEST_CASE("a noisy keypoint's length is flagged wide and corrected for jitter", "[keypoints]") {
  const CalibTemplate t = load_template_file(template_path("halpe26"));
  // 60 s: the median of a distance whose end jitters 25 mm per axis is known to about
  // 1.25 * 25 / sqrt(frames) mm, 0.5 mm here (6 s left 1.6 mm, as much as the 2.5 mm of
  // lengthening the test looks for).
  tools::SynthOptions long_trial = short_trial();
  long_trial.seconds = 60.0;
  tools::KeypointTrial trial = tools::make_keypoint_trial(truth_setup(t), long_trial, {});
  // 25 mm per axis on the right wrist only.
  const int wrist = trial.keypoints.find("RWrist");
  REQUIRE(wrist >= 0);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0.0, 0.025);
  for (std::size_t f = 0; f < trial.keypoints.frames(); ++f)
    trial.keypoints.at(f, static_cast<std::size_t>(wrist)) += draw_vector3(g, rng);
  const KeypointCalibration k = calibrate_keypoints(t, trial.keypoints, "noisy wrist");
  const KeypointLength& noisy = length_of(k, "r_wrist");
  CHECK(noisy.wide);
  CHECK(noisy.iqr_m > 0.02);
  CHECK_FALSE(length_of(k, "l_wrist").wide);
  CHECK_FALSE(length_of(k, "r_elbow").wide);
  // Jitter lengthens a distance on average; the correction takes most of that back.
  const double nominal = nominal_m(t, "r_wrist");
  INFO("raw " << noisy.median_raw_m * 1e3 << " corrected " << noisy.median_m * 1e3);
  CHECK(noisy.median_raw_m - nominal > 1e-3);
  CHECK(std::abs(noisy.median_m - nominal) < 0.5 * (noisy.median_raw_m - nominal));
  // The wrist's jitter is seen for what it is.
  for (const auto& [name, j] : k.jitter_m)
    if (name == "RWrist") CHECK(std::abs(j - 0.025) < 0.005);
}

TEST_CASE("every keypoint template tracks its rendered trial", "[keypoints]") {
  for (const char* name : {"halpe26", "coco17", "blazepose33"}) {
    eval::MarkerlessOptions o;
    o.template_path = template_path(name);
    o.seconds = 6.0;
    o.cases = {"clean", "jitter"};
    o.corruption.jitter_mm = 10.0;
    const std::vector<eval::MarkerlessRow> rows = eval::eval_markerless(o);
    REQUIRE(rows.size() == 2);
    INFO(name << ": clean " << rows[0].joint_rms_m * 1e3 << " mm, jitter "
              << rows[1].joint_rms_m * 1e3 << " mm");
    CHECK(rows[0].frames == 360);
    CHECK(rows[0].joint_rms_m < 2e-3);
    CHECK(rows[0].joint_max_m < 10e-3);
    CHECK(rows[0].length_error_max_m < 2e-3);
    // 10 mm per axis is 17 mm in 3D: the model's rigid segments and joint ranges keep the
    // joint centres nearer the truth than the keypoints are.
    CHECK(rows[1].joint_rms_m < 17e-3);
    CHECK(rows[1].joint_rms_m > rows[0].joint_rms_m);
  }
}

TEST_CASE("keypoint swaps are undone live and offline, and the offline filter does not smear them",
          "[keypoints][swap][filter]") {
  eval::MarkerlessOptions o;
  o.template_path = template_path("halpe26");
  o.seconds = 6.0;
  o.cases = {"swaps", "jitter"};
  o.corruption.jitter_mm = 10.0;
  o.path = "live";
  const std::vector<eval::MarkerlessRow> live = eval::eval_markerless(o);
  o.path = "offline";
  const std::vector<eval::MarkerlessRow> offline = eval::eval_markerless(o);
  REQUIRE(live.size() == 2);
  REQUIRE(offline.size() == 2);
  REQUIRE(live[0].swaps > 0);
  INFO("near swaps: live " << live[0].joint_rms_swapped_m * 1e3 << " mm, offline "
                           << offline[0].joint_rms_swapped_m * 1e3 << " mm; jitter live "
                           << live[1].joint_rms_m * 1e3 << " mm, offline "
                           << offline[1].joint_rms_m * 1e3 << " mm");
  // Without jitter the swapped frames track as the others do (a swap followed is 100s of mm).
  CHECK(live[0].joint_rms_swapped_m < 5e-3);
  CHECK(offline[0].joint_rms_swapped_m < 5e-3);
  // The zero-lag low-pass takes a good part of the jitter out, and adds no lag.
  CHECK(offline[1].joint_rms_m < 0.75 * live[1].joint_rms_m);
  CHECK(offline[1].lag_frames == 0);
}

TEST_CASE("the markerless generator is deterministic and injects what it reports",
          "[keypoints]") {
  const CalibTemplate t = load_template_file(template_path("halpe26"));
  const tools::SynthSetup setup = truth_setup(t);
  KeypointCorruption c;
  c.dropouts_per_s = 3.0;
  c.swaps_per_s = 2.0;
  c.seed = 11;
  const tools::KeypointTrial a = tools::make_keypoint_trial(setup, short_trial(), c);
  const tools::KeypointTrial b = tools::make_keypoint_trial(setup, short_trial(), c);
  REQUIRE(a.keypoints.positions_m.size() == b.keypoints.positions_m.size());
  for (std::size_t i = 0; i < a.keypoints.positions_m.size(); ++i)
    REQUIRE(same(a.keypoints.positions_m[i], b.keypoints.positions_m[i]));
  REQUIRE(a.injected.size() == b.injected.size());

  const std::size_t n = a.keypoints.markers(), frames = a.keypoints.frames();
  // Where each sample should come from: itself, nothing (dropout) or its mirror (swap).
  std::vector<int> source(frames * n);
  for (std::size_t i = 0; i < source.size(); ++i) source[i] = static_cast<int>(i % n);
  int dropouts = 0, swaps = 0, limb_swaps = 0;
  for (const InjectedRun& r : a.injected) {
    REQUIRE(r.frames >= 2);
    for (int f = r.first_frame; f < r.first_frame + r.frames; ++f) {
      if (r.kind == InjectedRun::Kind::dropout) {
        source[f * n + r.keypoints[0]] = -1;
        continue;
      }
      for (std::size_t p = 0; p + 1 < r.keypoints.size(); p += 2) {
        source[f * n + r.keypoints[p]] = r.keypoints[p + 1];
        source[f * n + r.keypoints[p + 1]] = r.keypoints[p];
      }
    }
    dropouts += r.kind == InjectedRun::Kind::dropout;
    swaps += r.kind != InjectedRun::Kind::dropout;
    limb_swaps += r.kind == InjectedRun::Kind::swap_limb;
    if (r.kind == InjectedRun::Kind::swap_limb) CHECK(r.keypoints.size() >= 4);
    if (r.kind == InjectedRun::Kind::swap_pair) CHECK(r.keypoints.size() == 2);
  }
  CHECK(dropouts == 18);  // 3/s over 6 s
  CHECK(swaps > 0);
  CHECK(limb_swaps > 0);
  int mismatches = 0;
  for (std::size_t f = 0; f < frames; ++f)
    for (std::size_t k = 0; k < n; ++k) {
      const int s = source[f * n + k];
      const Eigen::Vector3d expected =
          s < 0 ? Eigen::Vector3d::Constant(NAN) : a.truth.markers.at(f, static_cast<std::size_t>(s));
      mismatches += !same(a.keypoints.at(f, k), expected);
    }
  CHECK(mismatches == 0);
  // The left/right pairs are found by name.
  CHECK(mirrored_pairs({"RKnee", "LKnee", "Neck", "right_hip", "left_hip", "Nose"}) ==
        std::vector<std::pair<int, int>>{{0, 1}, {3, 4}});
}

TEST_CASE("keypoint template mistakes have their own messages", "[keypoints]") {
  const auto error = [](const nlohmann::json& doc) {
    try {
      load_template(doc, "bad.json");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  nlohmann::json doc = {
      {"format", "fabrikd-template/1"},
      {"kind", "keypoints"},
      {"units", "mm"},
      {"segments",
       {{{"name", "pelvis"},
         {"base", "mid"},
         {"points",
          {{"mid", {{"midpoint", {"r_hip", "l_hip"}}}},
           {"r_hip", {{"at", "RHip"}, {"target", "joint"}, {"rest", {0, 0, 90}}}},
           {"l_hip", {{"at", "LHip"}, {"target", "joint"}, {"rest", {0, 0, -90}}}}}}}}}};
  CHECK(error(doc).empty());
  nlohmann::json no_rest = doc;
  no_rest["segments"][0]["points"]["r_hip"].erase("rest");
  CHECK_THAT(error(no_rest), Catch::Contains("has no \"rest\" vector"));
  nlohmann::json zero_rest = doc;  // was said of the calibrated model: "segment ... no extent"
  zero_rest["segments"][0]["points"]["r_hip"]["rest"] = {0, 0, 0};
  CHECK_THAT(error(zero_rest), Catch::Contains("bad.json") &&
                                   Catch::Contains("/segments/0/points/r_hip/rest") &&
                                   Catch::Contains("has a \"rest\" vector of length 0"));
  nlohmann::json markers_kind = doc;
  markers_kind.erase("kind");
  markers_kind["segments"][0]["markers"] = {{"RHip", nlohmann::json::object()}};
  CHECK_THAT(error(markers_kind), Catch::Contains("belongs to keypoint templates"));
  nlohmann::json same_name = doc;
  same_name["segments"][0]["points"]["r_hip"]["at"] = "r_hip";
  CHECK_THAT(error(same_name), Catch::Contains("both named 'r_hip'"));
}
