// Offline fill from donor markers (tracking/donor_fill.hpp): a marker of a
// rigid cluster is reproduced from the cluster whatever else moves; too few
// donors give no fill; a better-scored skeleton frame outweighs donors that
// do not move with the marker.
#include <Eigen/Geometry>
#include <catch2/catch.hpp>
#include <cmath>
#include <vector>

#include "tracking/donor_fill.hpp"

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
