// Fills from donor markers. Offline (tracking/donor_fill.hpp): a marker of a
// rigid cluster is reproduced from the cluster whatever else moves; too few
// donors give no fill; a better-scored skeleton frame outweighs donors that
// do not move with the marker; the marker's coordinates in the donors' frame
// are interpolated linearly across the gap. Live (GapPredictor): triples
// weigh 1 / score^2; the skeleton competes only where two more markers of its
// segment hold it, and then gates a triple by its distance from the
// skeleton's fill.
#include <Eigen/Geometry>
#include <catch2/catch.hpp>
#include <cmath>
#include <vector>

#include "solver/model_builder.hpp"
#include "tracking/donor_fill.hpp"
#include "tracking/gap_predictor.hpp"

using namespace fabrik;

namespace {

// Markers 0-3 on one rigid body, 4-13 each on a body of its own (more than
// the donor candidates, so the ranking matters), at 100 Hz.
struct Scene {
  static constexpr std::size_t n = 14, frames = 240;
  std::vector<double> times_s;
  std::vector<Eigen::Vector3d> markers_m;
  std::vector<Eigen::Quaterniond> body_q;  // the rigid body's frame
  std::vector<Eigen::Vector3d> body_origin_m;
  Scene() {
    const Eigen::Vector3d local_m[4] = {
        {0.05, 0.02, 0.30}, {0.0, 0.0, 0.0}, {0.08, -0.03, 0.12}, {-0.06, 0.04, 0.20}};
    for (std::size_t f = 0; f < frames; ++f) {
      const double t = 0.01 * static_cast<double>(f);
      times_s.push_back(t);
      const Eigen::Quaterniond q =
          Eigen::AngleAxisd(1.2 * std::sin(2.1 * t), Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(0.8 * std::sin(3.3 * t + 0.4), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(0.5 * t, Eigen::Vector3d::UnitZ());
      const Eigen::Vector3d origin_m(0.4 * t, 0.1 * std::sin(5.0 * t), 1.0);
      body_q.push_back(q);
      body_origin_m.push_back(origin_m);
      for (const Eigen::Vector3d& l : local_m) markers_m.push_back(origin_m + q * l);
      // Markers that each move their own way, close to the body.
      for (int k = 0; k < 10; ++k)
        markers_m.push_back(origin_m + Eigen::Vector3d(0.2 * std::sin((4.0 + k) * t + k),
                                                       0.15 * std::cos((2.5 + k) * t),
                                                       0.03 * k + 0.05 * std::sin((7.0 + k) * t)));
    }
  }
};

}  // namespace

TEST_CASE("Donor fill: a marker of a rigid cluster is reproduced from the cluster", "[gaps][donors]") {
  const Scene s;
  std::vector<std::uint8_t> visible(Scene::frames * Scene::n, 1);
  const std::size_t first = 80, end = 150;
  for (std::size_t f = first; f < end; ++f) visible[f * Scene::n + 0] = 0;
  std::vector<Eigen::Vector3d> out(end - first);
  REQUIRE(fill_from_donors(Scene::frames, Scene::n, s.times_s, s.markers_m, visible, 0, first, end,
                           {}, out));
  double worst_m = 0.0;
  for (std::size_t f = first; f < end; ++f)
    worst_m = std::max(worst_m, (out[f - first] - s.markers_m[f * Scene::n]).norm());
  INFO("largest fill error " << worst_m * 1e3 << " mm");
  // The exact triple dominates; triples with an independent marker keep a
  // weight of (floor / their score)^2 relative to it: micrometres here.
  CHECK(worst_m < 2e-5);

  // The same at the start and at the end of the trial (one side only).
  for (const auto& [a, b] : {std::pair<std::size_t, std::size_t>{0, 60}, {180, Scene::frames}}) {
    std::vector<std::uint8_t> v(Scene::frames * Scene::n, 1);
    for (std::size_t f = a; f < b; ++f) v[f * Scene::n + 0] = 0;
    std::vector<Eigen::Vector3d> edge(b - a);
    REQUIRE(fill_from_donors(Scene::frames, Scene::n, s.times_s, s.markers_m, v, 0, a, b, {}, edge));
    double e_m = 0.0;
    for (std::size_t f = a; f < b; ++f) e_m = std::max(e_m, (edge[f - a] - s.markers_m[f * Scene::n]).norm());
    CHECK(e_m < 2e-5);
  }
}

TEST_CASE(
    "Donor fill: a gap clipped short of the trial's edge is filled from its one measured "
    "side",
    "[gaps][donors]") {
  // The marker is missing in frames 0-59; the fill is asked for 20-59 only (the frames before
  // 20 had no marker at all, as two_sided_fill clips them). Frame 19 is no side: the marker
  // was not measured there. Taken for one, its stale coordinates were blended into the fill.
  const Scene s;
  std::vector<std::uint8_t> visible(Scene::frames * Scene::n, 1);
  std::vector<Eigen::Vector3d> markers_m = s.markers_m;  // NaN where missing, as the fill has them
  for (std::size_t f = 0; f < 60; ++f) {
    visible[f * Scene::n + 0] = 0;
    markers_m[f * Scene::n + 0].setConstant(NAN);
  }
  std::vector<Eigen::Vector3d> out(40);
  REQUIRE(
      fill_from_donors(Scene::frames, Scene::n, s.times_s, markers_m, visible, 0, 20, 60, {}, out));
  double worst_m = 0.0;
  for (std::size_t f = 20; f < 60; ++f) {
    const double e_m = (out[f - 20] - s.markers_m[f * Scene::n]).norm();
    worst_m = std::isfinite(e_m) ? std::max(worst_m, e_m) : INFINITY;  // NaN: the stale side
  }
  INFO("largest fill error " << worst_m * 1e3 << " mm");
  CHECK(worst_m < 2e-5);
}

TEST_CASE("Donor fill: no fill without three donors measured through the gap", "[gaps][donors]") {
  const Scene s;
  std::vector<std::uint8_t> visible(Scene::frames * Scene::n, 1);
  const std::size_t first = 80, end = 150;
  // Only markers 1 and 2 stay measured through the gap.
  for (std::size_t f = first; f < end; ++f) {
    visible[f * Scene::n] = 0;
    for (std::size_t m = 3; m < Scene::n; ++m) visible[f * Scene::n + m] = 0;
  }
  std::vector<Eigen::Vector3d> out(end - first, Eigen::Vector3d::Constant(7.0));
  CHECK_FALSE(fill_from_donors(Scene::frames, Scene::n, s.times_s, s.markers_m, visible, 0, first,
                               end, {}, out));
  CHECK(out.front() == Eigen::Vector3d::Constant(7.0));  // untouched
  // Never measured: nothing to fill from.
  std::vector<std::uint8_t> never(Scene::frames * Scene::n, 1);
  for (std::size_t f = 0; f < Scene::frames; ++f) never[f * Scene::n] = 0;
  std::vector<Eigen::Vector3d> all(Scene::frames);
  CHECK_FALSE(fill_from_donors(Scene::frames, Scene::n, s.times_s, s.markers_m, never, 0, 0,
                               Scene::frames, {}, all));
}

TEST_CASE("Donor fill: a skeleton frame that follows the marker outweighs donors that do not",
          "[gaps][donors]") {
  const Scene s;
  std::vector<std::uint8_t> visible(Scene::frames * Scene::n, 1);
  const std::size_t first = 80, end = 150;
  // The cluster's other markers are lost too: only the independent ones remain as donors.
  for (std::size_t f = first; f < end; ++f)
    for (std::size_t m : {0, 1, 2, 3}) visible[f * Scene::n + m] = 0;
  std::vector<Eigen::Vector3d> truth(end - first), out(end - first);
  for (std::size_t f = first; f < end; ++f) truth[f - first] = s.markers_m[f * Scene::n];
  const FrameCandidate skeleton{s.body_q, s.body_origin_m, truth};
  double donor_share = -1.0;
  REQUIRE(fill_from_donors(Scene::frames, Scene::n, s.times_s, s.markers_m, visible, 0, first, end,
                           {}, out, &skeleton, &donor_share));
  double worst_m = 0.0;
  for (std::size_t f = first; f < end; ++f)
    worst_m = std::max(worst_m, (out[f - first] - truth[f - first]).norm());
  INFO("donor share " << donor_share << ", largest error " << worst_m * 1e3 << " mm");
  CHECK(donor_share < 0.01);
  CHECK(worst_m < 1e-3);
  // Without the skeleton the independent donors are refused: their best simulated gap is far off.
  CHECK_FALSE(fill_from_donors(Scene::frames, Scene::n, s.times_s, s.markers_m, visible, 0, first,
                               end, {}, out));
}

TEST_CASE("Donor fill: the marker's coordinates in the donors' frame are interpolated linearly "
          "across the gap",
          "[gaps][donors]") {
  // Three donors on a turning, moving body, in whose frame (origin at the
  // first, x towards the second, the third in the xy plane) the marker slides
  // at constant velocity: interpolating its coordinates linearly from the
  // frame before the gap to the frame after it is exact, and so is a
  // simulated gap.
  constexpr std::size_t n = 4, frames = 40, first = 15, end = 25;
  const Eigen::Vector3d donor_local_m[3] = {{0.0, 0.0, 0.0}, {0.1, 0.0, 0.0}, {0.0, 0.1, 0.0}};
  const Eigen::Vector3d start_local_m(0.05, 0.03, 0.08), velocity_m_per_s(0.2, -0.1, 0.05);
  std::vector<double> times_s;
  std::vector<Eigen::Vector3d> markers_m;
  std::vector<Eigen::Quaterniond> identity_q(frames, Eigen::Quaterniond::Identity());
  std::vector<Eigen::Vector3d> marker_m;  // the truth, per frame
  for (std::size_t f = 0; f < frames; ++f) {
    const double t_s = 0.01 * static_cast<double>(f);
    times_s.push_back(t_s);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(2.0 * t_s, Eigen::Vector3d(1, 2, 3).normalized()));
    const Eigen::Vector3d origin_m(0.5 * t_s, 1.0, -0.2 * t_s);
    marker_m.push_back(origin_m + q * (start_local_m + velocity_m_per_s * t_s));
    markers_m.push_back(marker_m.back());
    for (const Eigen::Vector3d& l : donor_local_m) markers_m.push_back(origin_m + q * l);
  }
  std::vector<std::uint8_t> visible(frames * n, 1);
  for (std::size_t f = first; f < end; ++f) visible[f * n] = 0;
  std::vector<Eigen::Vector3d> out(end - first);
  REQUIRE(fill_from_donors(frames, n, times_s, markers_m, visible, 0, first, end, {}, out));
  for (std::size_t f = first; f < end; ++f) {
    INFO("frame " << f);
    CHECK((out[f - first] - marker_m[f]).norm() < 1e-9);
  }

  // A skeleton frame that carries the marker rigidly (its origin on the
  // marker) scores 0 however gaps are interpolated; the donors score 0 only
  // when theirs are interpolated right. Both at the score floor: equal weights.
  const std::vector<Eigen::Vector3d> truth(marker_m.begin() + first, marker_m.begin() + end);
  const FrameCandidate skeleton{identity_q, marker_m, truth};
  double donor_share = -1.0;
  REQUIRE(fill_from_donors(frames, n, times_s, markers_m, visible, 0, first, end, {}, out,
                           &skeleton, &donor_share));
  CHECK(donor_share == Approx(0.5).margin(1e-9));
  for (std::size_t f = first; f < end; ++f) CHECK((out[f - first] - marker_m[f]).norm() < 1e-9);
}

namespace {

// The live fill (GapPredictor) driven without a solver: nothing moves but
// the markers made to, so the rest posture is the solved one every frame.
// A trunk carries two donor clusters, A (markers 3-5) and B (6-8); the arm
// carries marker 0, the one filled, and markers 1 and 2, which can hold the
// arm. Eight frames of history, then the gap starts in the ninth (frame 8).
struct LiveScene {
  static constexpr int n = 9, frames = 9, gap = 8;
  static constexpr int cluster_a = 3, cluster_b = 6;
  Model model;
  std::vector<int> points;
  std::vector<Eigen::Vector3d> rest_m;     // each marker where the rest posture has it
  std::vector<Eigen::Vector3d> markers_m;  // [frame * n + i]
  std::vector<std::uint8_t> seen;          // [frame * n + i]

  LiveScene() : model(build()) {
    const Posture rest = Posture::rest(model);
    for (const char* name : {"m", "h1", "h2", "a0", "a1", "a2", "b0", "b1", "b2"})
      points.push_back(model.find_point(name));
    for (int p : points) rest_m.push_back(rest.point_world_m(model, p));
    for (int f = 0; f < frames; ++f)
      markers_m.insert(markers_m.end(), rest_m.begin(), rest_m.end());
    seen.assign(static_cast<std::size_t>(frames * n), 1);
  }
  Eigen::Vector3d& at(int f, int i) { return markers_m[static_cast<std::size_t>(f * n + i)]; }
  std::uint8_t& seen_at(int f, int i) { return seen[static_cast<std::size_t>(f * n + i)]; }

  static Model build() {
    // Each cluster a right triangle: flat from no corner.
    SegmentSpec trunk, arm;
    trunk.name = "trunk";
    trunk.base = "root";
    trunk.points = {{"shoulder", {0.3, 0.0, 0.0}, false}};
    for (int k = 0; k < 2; ++k) {
      const Eigen::Vector3d corner_m(0.0, 0.0, 0.3 * k);
      const std::string c = k == 0 ? "a" : "b";
      trunk.points.push_back({c + "0", corner_m, true});
      trunk.points.push_back({c + "1", corner_m + Eigen::Vector3d(0.2, 0.0, 0.0), true});
      trunk.points.push_back({c + "2", corner_m + Eigen::Vector3d(0.0, 0.2, 0.0), true});
    }
    arm.name = "arm";
    arm.parent = "trunk";
    arm.base = "shoulder";
    arm.points = {{"m", {0.2, 0.1, 0.0}, true},
                  {"h1", {0.15, -0.05, 0.05}, true},
                  {"h2", {0.25, 0.0, -0.08}, true}};
    return build_model("live_donors", {trunk, arm}, Eigen::Vector3d::Zero());
  }

  // Marker 0's reported position in the last frame.
  Eigen::Vector3d fill(const PredictionSettings& settings) const {
    GapPredictor predictor(model, points, settings);
    const Posture posture = Posture::rest(model);
    std::vector<Eigen::Vector3d> targets_m(n), reported_m(n);
    std::vector<Eigen::Quaterniond> q_world(predictor.orientation_targets().size());
    std::vector<std::uint8_t> q_visible(q_world.size());
    std::vector<double> gap_s(n);
    for (int f = 0; f < frames; ++f) {
      const std::span<const Eigen::Vector3d> measured(markers_m.data() + f * n, n);
      const std::span<const std::uint8_t> seen_now(seen.data() + f * n, n);
      std::copy(measured.begin(), measured.end(), targets_m.begin());
      predictor.before_solve(0.01 * f, seen_now, targets_m, q_world, q_visible);
      for (int i = 0; i < n; ++i) reported_m[i] = posture.point_world_m(model, points[i]);
      predictor.after_solve(0.01 * f, posture, seen_now, measured, reported_m, gap_s);
    }
    return reported_m[0];
  }
};

PredictionSettings live_settings() {
  PredictionSettings s;
  s.enabled = true;
  s.donor_score_floor_m = 1e-3;
  s.donor_gate = 3.0;
  return s;
}

}  // namespace

TEST_CASE("Live donor fill: triples are averaged with weights 1 / score^2", "[gaps][donors]") {
  LiveScene s;
  const PredictionSettings settings = live_settings();
  const double floor_m = settings.donor_score_floor_m;
  // The arm's other markers are never measured: the skeleton does not compete.
  for (int f = 0; f < LiveScene::frames; ++f) s.seen_at(f, 1) = s.seen_at(f, 2) = 0;
  // A is measured in frames 0-4 and 7-8, B in 3-8: never together for a
  // hold of half the history (4 frames) plus its start, so no triple mixing
  // them is scored; A's and B's own triples are, each on one hold.
  for (int k = 0; k < 3; ++k) {
    for (int f : {5, 6}) s.seen_at(f, LiveScene::cluster_a + k) = 0;
    for (int f : {0, 1, 2}) s.seen_at(f, LiveScene::cluster_b + k) = 0;
  }
  // A stays with the marker: score 0, weight 1 / floor^2. B shakes by +-e
  // along z from frame to frame: held over an even number of frames, the
  // marker's coordinates in B's frame are off by 2e every other frame, an RMS
  // of sqrt(2) e = 2 floors, weight 1 / (4 floor^2).
  const double e_m = std::sqrt(2.0) * floor_m;
  for (int f = 0; f < LiveScene::frames; ++f)
    for (int k = 0; k < 3; ++k) s.at(f, LiveScene::cluster_b + k).z() += f % 2 == 0 ? e_m : -e_m;
  s.seen_at(LiveScene::gap, 0) = 0;
  // A puts the marker where it was; B, 2e further along z than at the
  // marker's last measurement (frame 7, odd).
  const Eigen::Vector3d a_m = s.rest_m[0], b_m = a_m + Eigen::Vector3d(0.0, 0.0, 2.0 * e_m);
  const Eigen::Vector3d expected_m = (a_m + 0.25 * b_m) / 1.25;
  const Eigen::Vector3d fill_m = s.fill(settings);
  INFO("fill " << (fill_m - a_m).transpose() * 1e3 << " mm from A's, expected "
               << (expected_m - a_m).transpose() * 1e3 << " mm");
  CHECK((fill_m - expected_m).norm() < 1e-9);
}

TEST_CASE("Live donor fill: the skeleton competes where two more markers hold its segment, and "
          "gates triples by their distance from it",
          "[gaps][donors]") {
  LiveScene s;
  PredictionSettings settings = live_settings();
  // Only the three steadiest candidates: A, whose distances to the marker do
  // not vary, and not the arm's others, which shake by 10 mm.
  settings.donor_candidates = 3;
  for (int f = 0; f < LiveScene::frames; ++f) {
    for (int k = 0; k < 3; ++k) s.seen_at(f, LiveScene::cluster_b + k) = 0;
    for (int h : {1, 2}) s.at(f, h).x() += f % 2 == 0 ? 0.010 : 0.0;
  }
  s.seen_at(LiveScene::gap, 0) = 0;
  const Eigen::Vector3d skeleton_m = s.rest_m[0];  // the arm has not moved
  const auto fill_with_a_moved = [&](double distance_m) {
    for (int k = 0; k < 3; ++k)
      s.at(LiveScene::gap, LiveScene::cluster_a + k) = s.rest_m[LiveScene::cluster_a + k] +
                                                       Eigen::Vector3d(0.0, distance_m, 0.0);
    return s.fill(settings);
  };
  const Eigen::Vector3d y = Eigen::Vector3d::UnitY();
  // The skeleton and A both held the marker exactly: both at the score floor,
  // equal weights before the gate. The gate's variance is gate^2 times the
  // sum of their squared scores, 2 (gate x floor)^2; at this distance the
  // Gaussian halves A's weight, so the fill is a third of the way to A's.
  const double k = settings.donor_gate, floor_m = settings.donor_score_floor_m;
  const double half_weight_m = 2.0 * k * floor_m * std::sqrt(std::log(2.0));
  SECTION("two more markers hold the arm: the skeleton competes") {
    CHECK((fill_with_a_moved(half_weight_m) - (skeleton_m + half_weight_m / 3.0 * y)).norm() <
          1e-9);
    // 50 mm is about 12 of the gate's standard deviations: A's weight vanishes.
    CHECK((fill_with_a_moved(0.050) - skeleton_m).norm() < 1e-9);
  }
  SECTION("one more marker holds the arm: the donors alone") {
    s.seen_at(LiveScene::gap, 2) = 0;
    CHECK((fill_with_a_moved(half_weight_m) - (skeleton_m + half_weight_m * y)).norm() < 1e-9);
    CHECK((fill_with_a_moved(0.050) - (skeleton_m + 0.050 * y)).norm() < 1e-9);
  }
}
