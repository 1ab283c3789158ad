// Orientation sensors in the Tracker and their calibration: readings become
// segment rotations through the mounting and the sensors' world; IMU-only
// frames set every joint and hold the root; pelvis markers plus limb sensors
// place every joint centre; unusable quaternions do not pull; calibration
// finds mountings and heading from one pose.
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <memory>
#include <numbers>

#include "calib/calib_template.hpp"
#include "calib/calibrate.hpp"
#include "calib/sensor_calibration.hpp"
#include "config/model_loader.hpp"
#include "synth/synthetic_motion.hpp"
#include "synth/synthetic_sensors.hpp"
#include "temp_file.hpp"
#include "test_models.hpp"
#include "tracking/tracker.hpp"

using namespace fabrik;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

struct Scene {
  std::shared_ptr<const Model> model = std::make_shared<const Model>(test::fullbody_model());
  TrackerSetup setup;
  std::vector<int> points;   // tracked marker points
  std::vector<int> segments;  // sensor segments
};

// Markers on the segments in `marker_segments` (all if empty: none when
// `no_markers`), one sensor per segment in `sensor_segments`, mounted as
// `sensors` says.
Scene scene(const std::vector<std::string>& marker_segments,
            const std::vector<std::string>& sensor_segments, bool no_markers = false) {
  Scene s;
  const Model& m = *s.model;
  s.setup.model = s.model;
  for (int p : m.marker_points()) {
    const std::string& seg = m.segments[m.points[p].segment].name;
    const bool take = !no_markers && (marker_segments.empty() ||
                                      std::find(marker_segments.begin(), marker_segments.end(),
                                                seg) != marker_segments.end());
    if (!take) continue;
    s.setup.markers.push_back({m.points[p].name, p, 0, 1.0});
    s.points.push_back(p);
  }
  for (const std::string& name : sensor_segments) s.segments.push_back(m.find_segment(name));
  s.setup.solver.root = RootMode::free;
  s.setup.solver.segment_fit = SegmentFit::rigid;
  s.setup.solver.tolerance_m = 1e-7;
  s.setup.solver.stall_tolerance_m = 1e-9;
  s.setup.solver.max_iterations = 500;
  return s;
}

std::vector<std::string> all_segments(const Model& m) {
  std::vector<std::string> names;
  for (const Segment& seg : m.segments) names.push_back(seg.name);
  return names;
}

// The tracker's sensors as the simulation mounted them (what calibration finds).
void mount(Scene& s, const SyntheticSensors& sim) {
  s.setup.sensors.q_world_sensors = sim.q_world_sensors();
  for (std::size_t k = 0; k < s.segments.size(); ++k)
    s.setup.sensors.sensors.push_back({"imu" + std::to_string(k), s.segments[k], 0, 1.0,
                                       sim.q_segment_sensor()[k]});
}

double worst_joint_error_rad(const Model& m, const Posture& a, const Posture& b) {
  double worst = 0.0;
  for (std::size_t s = 1; s < m.segments.size(); ++s) {
    const int p = m.segments[s].parent;
    const Eigen::Quaterniond ra = a.segments[p].q_world.conjugate() * a.segments[s].q_world;
    const Eigen::Quaterniond rb = b.segments[p].q_world.conjugate() * b.segments[s].q_world;
    worst = std::max(worst, ra.angularDistance(rb));
  }
  return worst;
}

}  // namespace

TEST_CASE("A sensor's reading becomes its segment's rotation through mounting and world",
          "[sensors]") {
  Scene s = scene({}, all_segments(*scene({}, {}).model));
  SyntheticSensors sim(s.segments, {}, 7);
  mount(s, sim);
  SensorTargets targets(s.setup.sensors, *s.model);
  SyntheticMotion motion(*s.model, {});
  Posture truth = Posture::rest(*s.model);
  std::vector<Eigen::Quaterniond> q(s.segments.size());
  std::vector<std::uint8_t> visible(q.size(), 1);
  for (double t : {0.0, 0.37, 1.3}) {
    motion.posture_at(t, truth);
    sim.sample(truth, t, q);
    REQUIRE(targets.set_measured(q, visible));
    for (std::size_t k = 0; k < q.size(); ++k)
      CHECK(targets.q_world_segment()[k].angularDistance(
                truth.segments[s.segments[k]].q_world) < 1e-12);
    targets.measure(truth);
    CHECK(targets.rms_rad() < 1e-12);
  }
  // A size mismatch changes nothing; empty spans occlude every sensor.
  CHECK_FALSE(targets.set_measured(std::span(q).first(3), std::span(visible).first(3)));
  REQUIRE(targets.set_measured({}, {}));
  CHECK(targets.occluded_count() == static_cast<int>(q.size()));
}

TEST_CASE("IMU-only frames set every joint and hold the root where it was", "[sensors]") {
  Scene s = scene({}, all_segments(*scene({}, {}).model), true);
  SyntheticSensors sim(s.segments, {}, 3);
  mount(s, sim);
  Tracker tracker(s.setup);
  SyntheticMotion motion(*s.model, {});
  Posture truth = Posture::rest(*s.model);
  std::vector<Eigen::Quaterniond> q(s.segments.size());
  const std::vector<std::uint8_t> q_visible(q.size(), 1);
  const Eigen::Vector3d rest_root_m = Posture::rest(*s.model).segments[0].base_world_m;
  double worst_rad = 0.0, worst_shift_m = 0.0;
  for (int f = 0; f < 60; ++f) {
    motion.posture_at(f / 100.0, truth);
    sim.sample(truth, f / 100.0, q);
    const TrackResult& r = tracker.track(f / 100.0, {}, {}, q, q_visible);
    REQUIRE(r.solve.status != SolveStatus::size_mismatch);
    CHECK(r.root_held);
    worst_rad = std::max(worst_rad, worst_joint_error_rad(*s.model, tracker.posture(), truth));
    worst_shift_m =
        std::max(worst_shift_m, (tracker.posture().segments[0].base_world_m - rest_root_m).norm());
    CHECK(r.sensor_rms_rad < 1e-3);
  }
  INFO("joint rotations follow the sensors; the root never leaves where the cold start put it");
  CHECK(worst_rad < 1e-3);
  CHECK(worst_shift_m < 1e-12);
  CHECK(test::max_joint_gap_m(*s.model, tracker.posture()) < 1e-9);
}

TEST_CASE("Pelvis markers plus sensors on every other segment place every joint centre",
          "[sensors]") {
  std::vector<std::string> others = all_segments(*scene({}, {}).model);
  others.erase(others.begin());  // the pelvis: its markers place it
  Scene s = scene({"pelvis"}, others);
  SyntheticSensors sim(s.segments, {}, 11);
  mount(s, sim);
  Tracker tracker(s.setup);
  SyntheticMotion motion(*s.model, {});
  Posture truth = Posture::rest(*s.model);
  std::vector<Eigen::Quaterniond> q(s.segments.size());
  const std::vector<std::uint8_t> q_visible(q.size(), 1);
  std::vector<Eigen::Vector3d> pos(s.points.size());
  const std::vector<std::uint8_t> visible(pos.size(), 1);
  double worst_m = 0.0;
  for (int f = 0; f < 40; ++f) {
    motion.posture_at(f / 100.0, truth);
    motion.sample(truth, s.points, 0.0, pos);
    sim.sample(truth, f / 100.0, q);
    const TrackResult& r = tracker.track(f / 100.0, pos, visible, q, q_visible);
    CHECK_FALSE(r.root_held);
    for (std::size_t j = 0; j < s.model->joints.size(); ++j)
      worst_m = std::max(worst_m, (r.joints_world_m[j] -
                                   truth.point_world_m(*s.model, s.model->joints[j].point))
                                      .norm());
  }
  CHECK(worst_m < 1e-4);
}

TEST_CASE("Unusable sensor quaternions are occluded and do not pull", "[sensors]") {
  Scene s = scene({"pelvis"}, {"r_shank", "l_shank", "r_thigh"});
  SyntheticSensors sim(s.segments, {}, 5);
  mount(s, sim);
  SyntheticMotion motion(*s.model, {});
  Posture truth = Posture::rest(*s.model);
  motion.posture_at(0.4, truth);
  std::vector<Eigen::Vector3d> pos(s.points.size());
  motion.sample(truth, s.points, 0.0, pos);
  const std::vector<std::uint8_t> visible(pos.size(), 1);
  std::vector<Eigen::Quaterniond> good(s.segments.size());
  sim.sample(truth, 0.4, good);
  const double nan = std::nan("");
  for (const Eigen::Quaterniond& bad :
       {Eigen::Quaterniond(0, 0, 0, 0), Eigen::Quaterniond(nan, 0, 0, 1),
        Eigen::Quaterniond(1.5, 0, 0, 0), Eigen::Quaterniond(INFINITY, 0, 0, 0)}) {
    // The same frame with the right shank's sensor flagged occluded, and with garbage instead.
    Tracker flagged(s.setup), garbage(s.setup);
    std::vector<Eigen::Quaterniond> q = good;
    std::vector<std::uint8_t> q_visible(q.size(), 1);
    q_visible[0] = 0;
    const TrackResult& a = flagged.track(0.0, pos, visible, q, q_visible);
    q_visible[0] = 1;
    q[0] = bad;
    const TrackResult& b = garbage.track(0.0, pos, visible, q, q_visible);
    CAPTURE(bad.coeffs().transpose());
    CHECK(b.sensor_occluded[0] == 1);
    CHECK(b.sensor_occluded_count == 1);
    CHECK(std::isnan(b.sensor_error_rad[0]));
    CHECK(a.sensor_occluded_count == 1);
    for (std::size_t i = 0; i < s.model->segments.size(); ++i)
      CHECK(flagged.posture().segments[i].q_world.angularDistance(
                garbage.posture().segments[i].q_world) < 1e-12);
  }
}

TEST_CASE("Calibration in the rest pose finds mountings and heading", "[sensors][calib]") {
  Scene s = scene({}, all_segments(*scene({}, {}).model), true);
  const Model& m = *s.model;
  SensorSection spec;
  spec.world.rotation_xyz_rad = Eigen::Vector3d(-90 * kDeg, 0, 0);
  spec.world.up = "y";
  spec.world.heading_sensor = "imu0";
  spec.world.heading_axis = "-y";
  std::vector<std::string> names;
  for (std::size_t k = 0; k < s.segments.size(); ++k) {
    names.push_back("imu" + std::to_string(k));
    SensorEntry entry;
    entry.sensor = names.back();
    entry.segment = m.segments[s.segments[k]].name;
    spec.entries.push_back(entry);
  }
  const Posture rest = Posture::rest(m);

  SECTION("random mountings: the calibrated sensors give back every segment's rotation") {
    SyntheticSensors sim(s.segments, {}, 21);
    std::vector<Eigen::Quaterniond> q(names.size());
    sim.sample(rest, 0.0, q);
    const calib::SensorCalibration c = calib::calibrate_sensors(spec, m, rest, names, q);
    s.setup.sensors = sensor_setup(c.section, m);
    SensorTargets targets(s.setup.sensors, m);
    SyntheticMotion motion(m, {});
    Posture truth = rest;
    motion.posture_at(0.8, truth);
    sim.sample(truth, 0.8, q);
    REQUIRE(targets.set_measured(q, std::vector<std::uint8_t>(q.size(), 1)));
    // A random mounting does not point the base sensor's axis forward, so the
    // heading found differs from the truth by some delta: the whole motion is
    // then seen from a world turned by delta about the vertical, and nothing else.
    const double delta = c.section.world.heading_rad - sim.heading_rad();
    const Eigen::Quaterniond turn(Eigen::AngleAxisd(delta, Eigen::Vector3d::UnitY()));
    for (std::size_t k = 0; k < q.size(); ++k)
      CHECK(targets.q_world_segment()[k].angularDistance(
                turn * truth.segments[s.segments[k]].q_world * turn.conjugate()) < 1e-9);
  }
  SECTION("a base sensor whose -y axis points forward gives the true heading") {
    // Mounted with its -y along the segment's front (x) and its x up.
    const Eigen::Quaterniond mounting(
        (Eigen::Matrix3d() << 0, -1, 0, 1, 0, 0, 0, 0, 1).finished());
    const double heading = 1.1;
    const Eigen::Quaterniond q_world_sensors =
        Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitY()) *
        Eigen::AngleAxisd(-90 * kDeg, Eigen::Vector3d::UnitX());
    std::vector<Eigen::Quaterniond> q(names.size(), q_world_sensors.conjugate() * mounting);
    const calib::SensorCalibration c = calib::calibrate_sensors(spec, m, rest, names, q);
    CHECK(c.section.world.heading_rad == Approx(heading).margin(1e-12));
    for (const SensorEntry& e : c.section.entries)
      CHECK(e.q_segment_sensor.angularDistance(mounting) < 1e-12);
    for (double d : c.mounting_deg) CHECK(d == Approx(90.0).margin(1e-9));
  }
  SECTION(
      "a missing sensor is left out, a missing heading sensor and a vertical heading axis "
      "are refused") {
    std::vector<Eigen::Quaterniond> q(names.size(), Eigen::Quaterniond::Identity());
    q[3] = Eigen::Quaterniond(0, 0, 0, 0);
    // As OpenSense's placer: the others placed, imu3 said and left out (it refused them all).
    const calib::SensorCalibration c = calib::calibrate_sensors(spec, m, rest, names, q);
    REQUIRE(c.section.entries.size() == names.size() - 1);
    for (const SensorEntry& e : c.section.entries) CHECK(e.sensor != "imu3");
    CHECK(c.mounting_deg.size() == names.size() - 1);
    CHECK_THAT(c.notes.at(0), Catch::StartsWith("no usable orientation in the calibration pose "
                                                "for: imu3: left out of the config"));
    q[0] = Eigen::Quaterniond(0, 0, 0, 0);
    CHECK_THROWS_WITH(calib::calibrate_sensors(spec, m, rest, names, q),
                      Catch::Contains("for 'imu0', the heading's sensor"));
    std::fill(q.begin(), q.end(), Eigen::Quaterniond(0, 0, 0, 0));
    spec.world.heading_sensor.clear();
    CHECK_THROWS_WITH(calib::calibrate_sensors(spec, m, rest, names, q),
                      Catch::Contains("for any sensor: imu0, imu1"));
    spec.world.heading_sensor = "imu0";
    std::fill(q.begin(), q.end(), Eigen::Quaterniond::Identity());
    spec.world.heading_axis = "z";  // the sensors' z is up: -90 deg about x takes it to y
    CHECK_THROWS_WITH(calib::calibrate_sensors(spec, m, rest, names, q),
                      Catch::Contains("within 10 deg of the vertical"));
  }
}

TEST_CASE("The mean of nearby rotations, its spread, and what it skips", "[sensors][calib]") {
  const Eigen::Quaterniond a(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()));
  const Eigen::Quaterniond b(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitX()));
  Eigen::Quaterniond minus_b = b;
  minus_b.coeffs() *= -1.0;  // the same rotation
  const double nan = std::nan("");
  const std::vector<Eigen::Quaterniond> q = {a, minus_b, Eigen::Quaterniond(nan, 0, 0, 0)};
  double spread = 0.0;
  const Eigen::Quaterniond mean = calib::mean_rotation(q, &spread);
  CHECK(mean.angularDistance(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()))) <
        1e-12);
  CHECK(spread == Approx(0.1).margin(1e-12));
  CHECK(std::isnan(calib::mean_rotation(std::span(q).last(1), &spread).w()));
}

TEST_CASE("Zero angles and a template's sensors' world follow the lab axes", "[sensors][calib]") {
  // The built-in model in a z-up lab with x forward (Vicon's, QTM's).
  std::ifstream in(std::string(FABRIK_SOURCE_DIR) + "/config/models/fullbody.json");
  nlohmann::json doc = nlohmann::json::parse(in);
  doc["lab_axes"] = {{"up", "+z"}, {"forward", "+x"}};
  const Model zup = load_model(doc, "fullbody_zup.json");
  REQUIRE(zup.lab_axes.up_lab == Eigen::Vector3d::UnitZ());
  // OpenSim's zero angles: every anatomical frame on the ground's axes, placed in the lab (the
  // subject lay along y, its sensors calibrated 17 deg off on OpenSense's walk).
  const Posture zero = calib::calibration_posture(zup, "zero_angles");
  for (std::size_t s = 0; s < zup.segments.size(); ++s) {
    CAPTURE(zup.segments[s].name);
    const Eigen::Quaterniond q_anatomical = zero.segments[s].q_world * zup.segments[s].q_anatomical;
    CHECK((q_anatomical * Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitZ()).norm() < 1e-12);
    CHECK((q_anatomical * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX()).norm() < 1e-12);
  }
  // OpenSense's sensors' world (z up, turned -90 deg about x onto a y-up ground) in the z-up
  // lab: no turn, up z, the heading kept.
  SensorWorld opensense;
  opensense.rotation_xyz_rad = Eigen::Vector3d(-90 * kDeg, 0, 0);
  opensense.up = "y";
  opensense.heading_rad = 0.7;
  const LabAxes ground, lab = zup.lab_axes;
  const SensorWorld in_lab = calib::sensor_world_in_lab(opensense, ground, lab);
  CHECK(in_lab.rotation_xyz_rad.norm() < 1e-12);
  CHECK(in_lab.up == "+z");
  CHECK(in_lab.heading_rad == 0.7);
  CHECK(in_lab.q_world_sensors().angularDistance(Eigen::Quaterniond(lab.r_from(ground)) *
                                                 opensense.q_world_sensors()) < 1e-12);
  // Any turn, any heading: the same physical world.
  opensense.rotation_xyz_rad = Eigen::Vector3d(0.3, -1.1, 2.0);
  const SensorWorld turned = calib::sensor_world_in_lab(opensense, ground, lab);
  CHECK(turned.q_world_sensors().angularDistance(Eigen::Quaterniond(lab.r_from(ground)) *
                                                 opensense.q_world_sensors()) < 1e-12);
  CHECK(calib::sensor_world_in_lab(opensense, lab, lab).rotation_xyz_rad ==
        opensense.rotation_xyz_rad);
  // A template's up is its lab's (y without lab_axes), as a config's is its model's.
  std::ifstream tin(std::string(FABRIK_SOURCE_DIR) + "/config/templates/opensense_gait2354.json");
  nlohmann::json t = nlohmann::json::parse(tin);
  t["sensors"]["world"]["up"] = "z";
  test::TempFile up_z(".json");
  std::ofstream(up_z.path()) << t.dump();
  CHECK_THROWS_WITH(calib::load_template_file(up_z.path()),
                    Catch::Contains("at /sensors/world/up: the model's vertical is its "
                                    "lab_axes' up (+y), not z"));
}
