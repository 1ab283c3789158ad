// Orientation targets in the solver: a segment turned towards a measured world
// rotation (an IMU, a rigid body), alone, mixed with markers, under priorities
// and within joint limits; rotations that are not usable do not pull.
#include <catch2/catch.hpp>
#include <cmath>
#include <memory>
#include <random>

#include "solver/fabrik_solver.hpp"
#include "solver/joint_angles.hpp"
#include "synth/random_draws.hpp"
#include "synth/synthetic_motion.hpp"
#include "test_models.hpp"

using namespace fabrik;

namespace {

SolverOptions tracking_options() {
  SolverOptions o;
  o.segment_fit = SegmentFit::rigid;
  o.root = RootMode::free;
  o.tolerance_m = 1e-7;
  o.stall_tolerance_m = 1e-9;
  o.max_iterations = 500;
  return o;
}

// The full-body model with its knees and elbows as hinges, its ankles as
// universal joints and its hips as limited balls, as a template would give it.
std::shared_ptr<const Model> limited_body() {
  const Model body = test::fullbody_model();
  std::vector<SegmentSpec> specs;
  for (const Segment& seg : body.segments) {
    SegmentSpec s;
    s.name = seg.name;
    s.parent = seg.parent < 0 ? "" : body.segments[seg.parent].name;
    s.base = body.points[seg.base_point].name;
    for (int i = seg.first_point + 1; i < seg.first_point + seg.point_count; ++i)
      s.points.push_back({body.points[i].name, body.points[i].p_local_m,
                          body.points[i].kind == PointKind::marker});
    const double deg = 3.141592653589793 / 180.0;
    if (s.name.find("shank") != std::string::npos) {
      s.joint.type = JointType::hinge;
      s.joint.min_rad[0] = -140 * deg;
      s.joint.max_rad[0] = 5 * deg;
    } else if (s.name.find("forearm") != std::string::npos) {
      s.joint.type = JointType::hinge;
      s.joint.min_rad[0] = 0.0;
      s.joint.max_rad[0] = 150 * deg;
    } else if (s.name.find("foot") != std::string::npos) {
      s.joint.type = JointType::universal;
      s.joint.min_rad[0] = -50 * deg;
      s.joint.max_rad[0] = 30 * deg;
      s.joint.min_rad[1] = -35 * deg;
      s.joint.max_rad[1] = 35 * deg;
    } else if (s.name.find("thigh") != std::string::npos) {
      s.joint.type = JointType::ball;
      s.joint.min_rad = {-40 * deg, -40 * deg, -40 * deg};
      s.joint.max_rad = {120 * deg, 40 * deg, 40 * deg};
    }
    specs.push_back(s);
  }
  return std::make_shared<const Model>(build_model("limited", specs, body.root_rest_m));
}

}  // namespace

TEST_CASE("Orientation targets alone turn every segment to its measured rotation",
          "[orientation]") {
  // One target per segment at the truth's rotation, no markers: the joint
  // angles follow exactly (positions of the root stay where they start:
  // rotations say nothing about translation).
  for (bool limits : {false, true}) {
    const auto m = limits ? limited_body() : std::make_shared<const Model>(test::fullbody_model());
    std::vector<OrientationTarget> targets;
    for (int s = 0; s < static_cast<int>(m->segments.size()); ++s) targets.push_back({s, 0, 1.0});
    FabrikSolver solver(m, {}, tracking_options(), targets);
    SyntheticMotion motion(*m, {});
    Posture truth = Posture::rest(*m), posture = Posture::rest(*m);
    std::vector<Eigen::Quaterniond> q(targets.size());
    const std::vector<std::uint8_t> visible(targets.size(), 1);
    double worst_rad = 0.0;
    for (int f = 0; f < 50; ++f) {
      motion.posture_at(0.03 * f, truth);
      for (std::size_t k = 0; k < q.size(); ++k) q[k] = truth.segments[k].q_world;
      const SolveResult r = solver.solve({}, {}, q, visible, posture);
      CAPTURE(limits, f, to_string(r.status), r.max_m);
      REQUIRE(r.status == SolveStatus::converged);
      for (std::size_t s = 0; s < q.size(); ++s)
        worst_rad = std::max(worst_rad, posture.segments[s].q_world.angularDistance(q[s]));
    }
    CAPTURE(limits, worst_rad);
    CHECK(worst_rad < 1e-5);
  }
}

TEST_CASE("Pelvis markers and limb orientation targets place every joint centre", "[orientation]") {
  const auto m = limited_body();
  std::vector<Target> points;
  std::vector<int> marker_points;
  for (int p : m->marker_points())
    if (m->segments[m->points[p].segment].name == "pelvis") {
      points.push_back({p, 0, 1.0});
      marker_points.push_back(p);
    }
  std::vector<OrientationTarget> orientations;
  for (int s = 1; s < static_cast<int>(m->segments.size()); ++s)
    orientations.push_back({s, 0, 1.0});
  FabrikSolver solver(m, points, tracking_options(), orientations);
  MotionSettings ms;
  ms.seed = 4;
  SyntheticMotion motion(*m, ms);
  Posture truth = Posture::rest(*m), posture = Posture::rest(*m);
  std::vector<Eigen::Vector3d> pos(points.size());
  std::vector<Eigen::Quaterniond> q(orientations.size());
  double worst_m = 0.0;
  for (int f = 0; f < 50; ++f) {
    motion.posture_at(0.03 * f, truth);
    motion.sample(truth, marker_points, 0.0, pos);
    for (std::size_t k = 0; k < q.size(); ++k)
      q[k] = truth.segments[orientations[k].segment].q_world;
    solver.solve(pos, std::vector<std::uint8_t>(pos.size(), 1), q,
                 std::vector<std::uint8_t>(q.size(), 1), posture);
    for (const Joint& j : m->joints)
      worst_m = std::max(
          worst_m, (posture.point_world_m(*m, j.point) - truth.point_world_m(*m, j.point)).norm());
  }
  CAPTURE(worst_m);
  CHECK(worst_m < 1e-4);
}

TEST_CASE("A stronger orientation target wins over a conflicting weaker marker", "[orientation]") {
  const Model m = test::chain_model(3, 0.3);
  const int tip = m.find_point("j3");
  SolverOptions o = tracking_options();
  o.root = RootMode::fixed;
  // The last segment must point along +x (a strong IMU); its tip marker (weak)
  // wants it to point along -x.
  const Eigen::Quaterniond along_x =
      Eigen::Quaterniond::FromTwoVectors(m.points[tip].p_local_m, Eigen::Vector3d::UnitX());
  const Eigen::Vector3d tip_target(-0.5, 0.5, 0.0);
  for (int imu_level : {1, -1}) {
    FabrikSolver solver(m, {{tip, 0, 1.0}}, o, {{2, imu_level, 1.0}});
    Posture posture = Posture::rest(m);
    solver.solve(std::vector<Eigen::Vector3d>{tip_target}, std::vector<std::uint8_t>{1},
                 std::vector<Eigen::Quaterniond>{along_x}, std::vector<std::uint8_t>{1}, posture);
    const double imu_error_rad = posture.segments[2].q_world.angularDistance(along_x);
    CAPTURE(imu_level, imu_error_rad, solver.target_distances_m()[0]);
    if (imu_level > 0)
      CHECK(imu_error_rad < 1e-3);  // the strong rotation is met
    else
      CHECK(imu_error_rad > 0.5);  // the strong marker wins instead
  }
}

TEST_CASE("A rotation that is not finite or not a rotation does not pull", "[orientation]") {
  const Model m = test::chain_model(2, 0.3);
  FabrikSolver solver(m, {}, tracking_options(), {{1, 0, 1.0}});
  for (const Eigen::Quaterniond& bad :
       {Eigen::Quaterniond(std::nan(""), 0, 0, 0), Eigen::Quaterniond(0, 0, 0, 0),
        Eigen::Quaterniond(INFINITY, 0, 0, 0)}) {
    Posture posture = Posture::rest(m);
    const SolveResult r = solver.solve({}, {}, std::vector<Eigen::Quaterniond>{bad},
                                       std::vector<std::uint8_t>{1}, posture);
    CHECK(r.status == SolveStatus::no_targets);
    CHECK(posture.segments[1].q_world.coeffs().allFinite());
  }
  Posture posture = Posture::rest(m);
  CHECK(solver.solve({}, {}, {}, {}, posture).status == SolveStatus::size_mismatch);
}

TEST_CASE("Property: random trees with orientation targets stay rigid and within their limits",
          "[orientation][property]") {
  std::mt19937_64 rng(31);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int trial = 0; trial < 40; ++trial) {
    const auto m = limited_body();
    std::vector<OrientationTarget> orientations;
    std::vector<Eigen::Quaterniond> q;
    for (int s = 0; s < static_cast<int>(m->segments.size()); ++s)
      if (g(rng) > 0.3) {
        orientations.push_back({s, static_cast<int>(std::abs(g(rng))), 1.0});
        q.push_back(draw_rotation(g, rng));
      }
    std::vector<Target> points;
    std::vector<Eigen::Vector3d> pos;
    for (int p : m->marker_points())
      if (g(rng) > 1.0) {
        points.push_back({p, 0, 1.0});
        pos.push_back(draw_vector3(g, rng));
      }
    FabrikSolver solver(m, points, tracking_options(), orientations);
    Posture posture = Posture::rest(*m);
    solver.solve(pos, std::vector<std::uint8_t>(pos.size(), 1), q,
                 std::vector<std::uint8_t>(q.size(), 1), posture);
    CAPTURE(trial);
    REQUIRE(test::max_rigidity_error(*m, posture) < 1e-9);
    REQUIRE(test::max_joint_gap_m(*m, posture) < 1e-9);
    for (int s = 1; s < static_cast<int>(m->segments.size()); ++s)
      REQUIRE(within_limits(m->segments[s].joint, joint_angles_rad(*m, posture, s), 1e-9));
  }
}
