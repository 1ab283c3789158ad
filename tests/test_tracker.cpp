// The Tracker: occlusion (absent, flagged, non-finite), the hold policy and
// its expiry, residuals over measured markers only, size checks, cold and
// warm starts.
#include <catch2/catch.hpp>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>

#include "synth/synthetic_motion.hpp"
#include "test_models.hpp"
#include "tracking/tracker.hpp"

using namespace fabrik;

namespace {

struct Scene {
  std::shared_ptr<const Model> model;
  TrackerSetup setup;
  std::vector<int> points;
};

Scene fullbody_scene(double hold_s) {
  Scene s;
  s.model = std::make_shared<const Model>(test::fullbody_model());
  s.setup.model = s.model;
  for (int p : s.model->marker_points()) {
    s.setup.markers.push_back({s.model->points[p].name, p, 0, 1.0});
    s.points.push_back(p);
  }
  s.setup.solver.root = RootMode::free;
  s.setup.solver.segment_fit = SegmentFit::rigid;
  s.setup.solver.tolerance_m = 1e-4;
  s.setup.solver.stall_tolerance_m = 1e-5;
  s.setup.occlusion.hold_s = hold_s;
  s.setup.occlusion.hold_level = -1;
  return s;
}

// The scene's markers at the synthetic motion's posture at 0.2 s, measured exactly.
std::vector<Eigen::Vector3d> sampled_markers(const Scene& s) {
  SyntheticMotion motion(*s.model, {});
  Posture truth = Posture::rest(*s.model);
  motion.posture_at(0.2, truth);
  std::vector<Eigen::Vector3d> pos(s.points.size());
  motion.sample(truth, s.points, 0.0, pos);
  return pos;
}

}  // namespace

TEST_CASE("A non-finite coordinate is occluded even when flagged visible", "[tracker]") {
  Scene s = fullbody_scene(0.0);
  Tracker tracker(s.setup);
  std::vector<Eigen::Vector3d> pos = sampled_markers(s);
  std::vector<std::uint8_t> visible(pos.size(), 1);
  tracker.track(0.0, pos, visible);
  pos[3].y() = std::nan("");
  pos[7].z() = INFINITY;
  const TrackResult& r = tracker.track(0.01, pos, visible);
  INFO("markers with a NaN or infinite coordinate must count as occluded");
  CHECK(r.occluded[3] == 1);
  CHECK(r.occluded[7] == 1);
  CHECK(r.occluded_count == 2);
  CHECK(r.residual_count == static_cast<int>(pos.size()) - 2);
  CHECK(std::isfinite(r.residual_rms_m));
  for (const Eigen::Vector3d& m : r.markers_world_m) CHECK(m.allFinite());
  for (const Eigen::Vector3d& j : r.joints_world_m) CHECK(j.allFinite());
}

TEST_CASE("A held marker stops being held, and stops pulling, after hold_s", "[tracker]") {
  Scene s = fullbody_scene(0.1);
  Tracker tracker(s.setup);
  SyntheticMotion motion(*s.model, {});
  Posture truth = Posture::rest(*s.model);
  std::vector<Eigen::Vector3d> pos(s.points.size());
  std::vector<std::uint8_t> visible(pos.size(), 1);
  const int hidden = 10;  // a marker occluded from 0.5 s on (last seen at 0.49 s)
  int held_frames = 0, released_frames = 0;
  for (int f = 0; f <= 100; ++f) {
    const double t = 0.01 * f;
    motion.posture_at(t, truth);
    motion.sample(truth, s.points, 0.0, pos);
    visible[hidden] = t < 0.5 - 1e-9 ? 1 : 0;
    const TrackResult& r = tracker.track(t, pos, visible);
    if (t < 0.5 - 1e-9) {
      CHECK(r.held[hidden] == 0);
    } else if (t - 0.49 <= 0.1 + 1e-9) {  // last seen at 0.49 s
      CAPTURE(t);
      CHECK(r.held[hidden] == 1);
      ++held_frames;
    } else {
      CAPTURE(t);
      INFO("an occluded marker is held for hold_s (0.1 s), then released");
      CHECK(r.held[hidden] == 0);
      CHECK(r.occluded[hidden] == 1);
      ++released_frames;
    }
  }
  CHECK(held_frames >= 10);
  CHECK(released_frames >= 30);
}

TEST_CASE("A held marker pulls its point towards its last position", "[tracker]") {
  // With the rest of a segment's markers gone too, only the hold keeps the
  // point where it was last seen: with holding off, it drifts with the others.
  for (double hold_s : {0.0, 10.0}) {
    Scene s = fullbody_scene(hold_s);
    Tracker tracker(s.setup);
    SyntheticMotion motion(*s.model, {});
    Posture truth = Posture::rest(*s.model);
    std::vector<Eigen::Vector3d> pos(s.points.size());
    std::vector<std::uint8_t> visible(pos.size(), 1);
    motion.posture_at(0.0, truth);
    motion.sample(truth, s.points, 0.0, pos);
    tracker.track(0.0, pos, visible);
    const Eigen::Vector3d last_seen = pos[0];
    visible[0] = 0;
    pos[0] = Eigen::Vector3d::Constant(NAN);
    const TrackResult& r = tracker.track(0.01, pos, visible);
    CAPTURE(hold_s);
    CHECK(r.held[0] == (hold_s > 0.0 ? 1 : 0));
    if (hold_s > 0.0) CHECK((r.markers_world_m[0] - last_seen).norm() < 2e-3);
  }
}

TEST_CASE("Inputs of the wrong size give a status, not an exception", "[tracker]") {
  Scene s = fullbody_scene(0.0);
  Tracker tracker(s.setup);
  std::vector<Eigen::Vector3d> pos(s.points.size() - 1, Eigen::Vector3d::Zero());
  std::vector<std::uint8_t> visible(s.points.size() - 1, 1);
  const TrackResult& r = tracker.track(0.0, pos, visible);
  CHECK(r.solve.status == SolveStatus::size_mismatch);
}

TEST_CASE("A frame refused for its sizes gives no verdict, not the last frame's", "[tracker]") {
  Scene s = fullbody_scene(0.0);
  Tracker tracker(s.setup);
  std::vector<Eigen::Vector3d> pos = sampled_markers(s);
  std::vector<std::uint8_t> visible(pos.size(), 1);
  visible[3] = 0;  // one occluded: the count the refused frame must not keep
  const TrackResult& good = tracker.track(0.0, pos, visible);
  REQUIRE(good.quality == FitQuality::good);
  REQUIRE(good.occluded_count == 1);
  const Posture before = tracker.posture();
  const TrackResult& r = tracker.track(0.01, std::span(pos).first(pos.size() - 1),
                                       std::span(visible).first(pos.size() - 1));
  CHECK(r.solve.status == SolveStatus::size_mismatch);
  CHECK(r.quality == FitQuality::none);  // was good: a loop counting good frames counted it
  CHECK(r.residual_count == 0);
  CHECK(r.residual_rms_m == 0.0);
  CHECK(r.worst_marker == -1);
  CHECK(r.occluded_count == 0);
  CHECK(tracker.posture().segments[0].base_world_m == before.segments[0].base_world_m);
}

TEST_CASE("A frame with a time that is not finite is refused with a status, the state kept",
          "[tracker]") {
  Scene s = fullbody_scene(0.0);
  Tracker tracker(s.setup);
  std::vector<Eigen::Vector3d> pos = sampled_markers(s);
  std::vector<std::uint8_t> visible(pos.size(), 1);
  tracker.track(0.0, pos, visible);
  visible[3] = 0;  // a gap whose age must run on through the refused frames
  for (int f = 1; f <= 10; ++f) tracker.track(0.01 * f, pos, visible);
  const Posture before = tracker.posture();
  for (double bad : {double(NAN), double(INFINITY), -double(INFINITY)}) {
    CAPTURE(bad);
    const TrackResult& r = tracker.track(bad, pos, visible);
    CHECK(r.solve.status == SolveStatus::non_finite_input);
    CHECK(r.quality == FitQuality::none);
    CHECK(tracker.posture().segments[0].base_world_m == before.segments[0].base_world_m);
  }
  // The next frame goes on as if the refused ones had not come: warm, the gap 0.11 s old (a
  // NaN time read as a long gap started cold and restarted the gap's age).
  const TrackResult& next = tracker.track(0.11, pos, visible);
  CHECK_FALSE(next.cold_start);
  CHECK(next.gap_s[3] == Approx(0.11).margin(1e-9));
}

TEST_CASE(
    "A marker's gap age runs on across cold starts and restarts with a clock that went "
    "back",
    "[tracker]") {
  Scene s = fullbody_scene(0.0);
  Tracker tracker(s.setup);
  REQUIRE(s.setup.cold_start.after_gap_s < 1.0);
  std::vector<Eigen::Vector3d> pos = sampled_markers(s);
  std::vector<std::uint8_t> visible(pos.size(), 1);
  tracker.track(0.0, pos, visible);
  visible[3] = 0;
  // Frames 1 s apart: each starts cold. The age read 0 on every one of them.
  for (int f = 1; f <= 4; ++f) {
    const TrackResult& r = tracker.track(1.0 * f, pos, visible);
    CAPTURE(f);
    REQUIRE(r.cold_start);
    CHECK(r.gap_s[3] == Approx(1.0 * f));
    CHECK(r.gap_s[4] == 0.0);  // measured
  }
  // The clock goes back (a source restarted): the age counts from there, not from -996 s.
  CHECK(tracker.track(-1000.0, pos, visible).gap_s[3] == 0.0);
  CHECK(tracker.track(-999.99, pos, visible).gap_s[3] == Approx(0.01));
  // A marker never measured since the start is as old as the stream.
  Tracker fresh(s.setup);
  fresh.track(5.0, pos, visible);
  CHECK(fresh.track(7.0, pos, visible).gap_s[3] == Approx(2.0));
}

TEST_CASE(
    "Frames with nothing measured past the cold-start gap hold the last pose, not the rest "
    "posture",
    "[tracker]") {
  Scene s = fullbody_scene(0.0);
  Tracker tracker(s.setup);
  REQUIRE(s.setup.cold_start.after_gap_s == Approx(0.5));
  std::vector<Eigen::Vector3d> pos = sampled_markers(s);
  std::vector<std::uint8_t> visible(pos.size(), 1);
  for (int f = 0; f <= 10; ++f) tracker.track(0.01 * f, pos, visible);
  const Posture held = tracker.posture();
  const Posture rest = Posture::rest(*s.model);
  double turned_rad = 0.0;  // the held pose is not the rest posture
  for (std::size_t k = 1; k < held.segments.size(); ++k)
    turned_rad =
        std::max(turned_rad, held.segments[k].q_world.angularDistance(rest.segments[k].q_world));
  REQUIRE(turned_rad > 0.1);
  // Every marker gone for 1 s: at 0.6 s into it the cold start handed back the rest posture.
  std::fill(visible.begin(), visible.end(), 0);
  for (int f = 11; f <= 110; ++f) {
    const TrackResult& r = tracker.track(0.01 * f, pos, visible);
    CAPTURE(f);
    REQUIRE(r.solve.status == SolveStatus::no_targets);
    CHECK_FALSE(r.cold_start);
    for (std::size_t k = 0; k < held.segments.size(); ++k) {
      CHECK(tracker.posture().segments[k].base_world_m == held.segments[k].base_world_m);
      CHECK(tracker.posture().segments[k].q_world.coeffs() == held.segments[k].q_world.coeffs());
    }
  }
  // The markers back: a cold start, from rest as always, onto them.
  std::fill(visible.begin(), visible.end(), 1);
  const TrackResult& back = tracker.track(1.11, pos, visible);
  CHECK(back.cold_start);
  CHECK(back.residual_rms_m < 1e-3);
}

TEST_CASE("A moved-from tracker answers with a status, not a crash", "[tracker]") {
  Scene s = fullbody_scene(0.0);
  Tracker first(s.setup);
  Tracker second(std::move(first));
  std::vector<Eigen::Vector3d> pos(s.points.size(), Eigen::Vector3d::Zero());
  std::vector<std::uint8_t> visible(pos.size(), 1);
  const TrackResult& r = first.track(0.0, pos, visible);  // NOLINT(bugprone-use-after-move)
  CHECK(r.solve.status == SolveStatus::wrong_workspace);
  CHECK(r.joints_world_m.empty());
  CHECK(first.marker_count() == 0);  // NOLINT(bugprone-use-after-move)
  first.reset();                     // NOLINT(bugprone-use-after-move)
  CHECK(second.track(0.0, pos, visible).solve.status != SolveStatus::wrong_workspace);
}

TEST_CASE("Tracker settings that cannot run are refused at setup, with their names", "[tracker]") {
  auto refused = [](auto&& change) {
    Scene s = fullbody_scene(0.0);
    change(s.setup);
    try {
      Tracker tracker(s.setup);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  CHECK_THAT(refused([](TrackerSetup& t) { t.quality.rms_m = NAN; }),
             Catch::Contains("quality.rms_m must be a finite number from 0 up (is nan)"));
  // The config reader's least, from the same owner: a cutoff of 0 froze every marker.
  CHECK_THAT(refused([](TrackerSetup& t) { t.smoothing.min_cutoff_hz = 0.0; }),
             Catch::Contains("smoothing.min_cutoff_hz must be a finite number from 0.001 up"));
  CHECK_THAT(refused([](TrackerSetup& t) { t.confidence.threshold = 1.5; }),
             Catch::Contains("confidence.threshold must be a finite number from 0 to 1 (is 1.5)"));
  CHECK_THAT(refused([](TrackerSetup& t) { t.occlusion.hold_s = -1e-7; }),
             Catch::Contains("(is -1e-07)"));
  CHECK_THAT(refused([](TrackerSetup& t) { t.occlusion.hold_s = -1.0; }),
             Catch::Contains("occlusion.hold_s"));
  CHECK_THAT(refused([](TrackerSetup& t) { t.solver.tolerance_m = NAN; }),
             Catch::Contains("solver: tolerance_m"));
  CHECK_THAT(refused([](TrackerSetup& t) { t.cold_start.max_iterations = 0; }),
             Catch::Contains("cold_start.max_iterations must be at least 1"));
  CHECK_THAT(refused([](TrackerSetup& t) { t.outliers.min_markers = 2; }),
             Catch::Contains("outliers.min_markers must be at least 3 (is 2)"));
  CHECK_THAT(refused([](TrackerSetup& t) { t.outliers.max_per_frame = -1; }),
             Catch::Contains("outliers.max_per_frame must not be negative"));
  CHECK_THAT(refused([](TrackerSetup& t) { t.model = nullptr; }), Catch::Contains("no model"));
  CHECK(refused([](TrackerSetup&) {}) == "accepted");
}

TEST_CASE("reset() makes the next frame start cold from rest", "[tracker]") {
  Scene s = fullbody_scene(0.0);
  Tracker tracker(s.setup);
  SyntheticMotion motion(*s.model, {});
  Posture truth = Posture::rest(*s.model);
  std::vector<Eigen::Vector3d> pos(s.points.size());
  std::vector<std::uint8_t> visible(pos.size(), 1);
  motion.posture_at(0.5, truth);
  motion.sample(truth, s.points, 0.0, pos);
  const int cold = tracker.track(0.0, pos, visible).solve.iterations;
  const int warm = tracker.track(0.01, pos, visible).solve.iterations;
  tracker.reset();
  const int after_reset = tracker.track(0.02, pos, visible).solve.iterations;
  CAPTURE(cold, warm, after_reset);
  CHECK(warm < cold);
  CHECK(after_reset == cold);
}
