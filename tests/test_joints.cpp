// Joint limits inside the solvers: every limited joint ends within its ranges,
// hinges keep their child in their plane, geometry stays rigid, and a target
// moving across a limit gives a continuous angle (no flips to the other side).
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <numbers>
#include <random>

#include "solver/fabrik_solver.hpp"
#include "solver/jacobian_solver.hpp"
#include "solver/joint_angles.hpp"
#include "solver/joint_fit.hpp"
#include "solver/model_builder.hpp"
#include "synth/random_draws.hpp"
#include "synth/synthetic_motion.hpp"
#include "test_models.hpp"

using namespace fabrik;
using fabrik::test::max_hinge_plane_m;
using fabrik::test::max_joint_gap_m;
using fabrik::test::max_limit_excess_rad;
using fabrik::test::max_rigidity_error;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

std::vector<std::uint8_t> all_visible(std::size_t n) {
  return std::vector<std::uint8_t>(n, 1);
}

// Rigid fits to a tight tolerance, the stall rule at a hundredth of it, 200 iterations.
SolverOptions tight_options(double tolerance_m, RootMode root = RootMode::fixed) {
  SolverOptions o;
  o.segment_fit = SegmentFit::rigid;
  o.root = root;
  o.tolerance_m = tolerance_m;
  o.stall_tolerance_m = tolerance_m / 100.0;
  o.max_iterations = 200;
  return o;
}

Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return draw_rotation(g, rng).toRotationMatrix();
}

// A random tree whose segments have random anatomical frames and random
// joint types with ranges around the rest angles.
Model random_joint_model(std::mt19937_64& rng, int n_segments) {
  std::vector<SegmentSpec> specs = test::random_tree_specs(rng, n_segments);
  std::uniform_int_distribution<int> type(0, 4);
  std::uniform_real_distribution<double> width(0.1, 1.3);
  // Anatomical frames whose rest angles keep a_x away from +-90 degrees,
  // where Cardan angles are singular (as anatomical frames of real joints do).
  for (SegmentSpec& s : specs) s.anatomical = random_rotation(rng);
  for (bool again = true; again;) {
    again = false;
    const Model plain = build_model("random", specs, Eigen::Vector3d::Zero());
    for (const Segment& seg : plain.segments)
      if (seg.parent >= 0 && std::abs(joint_angles_rad(plain, Posture::rest(plain),
                                                       plain.find_segment(seg.name))[1]) > 1.2) {
        for (SegmentSpec& s : specs)
          if (s.name == seg.name) s.anatomical = random_rotation(rng);
        again = true;
      }
  }
  const Model plain = build_model("random", specs, Eigen::Vector3d::Zero());
  for (SegmentSpec& s : specs) {
    if (s.parent.empty()) continue;
    const int seg = plain.find_segment(s.name);
    const Eigen::Vector3d rest = cardan_zxy(
        relative_anatomical(plain, Posture::rest(plain), seg, plain.segments[seg].parent));
    s.joint.type = static_cast<JointType>(type(rng));
    for (int k = 0; k < 3; ++k) {
      const double bound = k == 1 ? std::numbers::pi / 2 : std::numbers::pi;
      s.joint.min_rad[k] = std::max(-bound, rest[k] - width(rng));
      s.joint.max_rad[k] = std::min(bound, rest[k] + width(rng));
    }
  }
  return build_model("random", specs, Eigen::Vector3d::Zero());
}

}  // namespace

TEST_CASE("Turn arithmetic agrees with the angle form of the joint fit", "[joints]") {
  std::mt19937_64 rng(7), axis_rng(8);
  std::uniform_real_distribution<double> u(-1.0, 1.0), angle(-3.0, 3.0), width(0.05, 2.5);
  for (int trial = 0; trial < 2000; ++trial) {
    JointLimits j;
    j.type = static_cast<JointType>(1 + trial % 3);  // ball, universal, hinge
    for (int k = 0; k < 3; ++k) {
      // As the model builder has it: a_x 0.01 rad short of the singular +-90 degrees.
      const double bound = k == 1 ? std::numbers::pi / 2 - 0.01 : std::numbers::pi;
      const double c = std::clamp(angle(rng), -bound, bound), w = width(rng);
      j.min_rad[k] = std::max(-bound, c - w);
      j.max_rad[k] = std::min(bound, c + w);
      j.rest_rad[k] = std::clamp(c + 0.3 * u(rng), j.min_rad[k], j.max_rad[k]);
    }
    if (j.type == JointType::universal) j.min_rad[2] = j.max_rad[2] = j.rest_rad[2];
    if (j.type == JointType::hinge)
      for (int k : {1, 2}) j.min_rad[k] = j.max_rad[k] = j.rest_rad[k];
    Eigen::Matrix3d b;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) b(r, c) = u(rng);
    const Eigen::Vector3d start =
        draw_vector3(angle, rng).cwiseProduct(Eigen::Vector3d(1.0, 0.5, 1.0));
    const Eigen::Vector3d by_angles = fit_joint_angles(b, j, start, 2);
    Turns turns;
    for (int k = 0; k < 3; ++k) turns[k] = {std::cos(start[k]), std::sin(start[k])};
    fit_joint_turns(b, JointArcs(j), turns, 2);
    CAPTURE(trial, static_cast<int>(j.type));
    for (int k = 0; k < 3; ++k) {
      CHECK(std::abs(std::remainder(std::atan2(turns[k].s, turns[k].c) - by_angles[k],
                                    2 * std::numbers::pi)) < 1e-9);
      CHECK(by_angles[k] >= j.min_rad[k] - 1e-12);
      CHECK(by_angles[k] <= j.max_rad[k] + 1e-12);
    }
    // A turn about an axis as a quaternion; a turn the clamp put on either bound is at_bound,
    // one well inside is not. (Its own engine: the fits above keep their draws.)
    const Eigen::Vector3d axis = draw_vector3(u, axis_rng).normalized();
    const Turn t0{std::cos(start[0]), std::sin(start[0])};
    CHECK(quaternion_about(t0, axis).angularDistance(
              Eigen::Quaterniond(Eigen::AngleAxisd(start[0], axis))) < 1e-12);
    const JointArcs arcs(j);
    if (!arcs.held[0]) {
      const double mid_rad = 0.5 * (j.min_rad[0] + j.max_rad[0]);
      const Turn inside{std::cos(mid_rad), std::sin(mid_rad)};
      CHECK_FALSE(arcs.at_bound(0, inside));
      for (double out_rad : {j.max_rad[0] + 0.01, j.min_rad[0] - 0.01}) {
        const Turn beyond{std::cos(out_rad), std::sin(out_rad)};
        if (!arcs.inside(0, beyond)) CHECK(arcs.at_bound(0, arcs.clamp(0, beyond, inside)));
      }
    }
  }
}

TEST_CASE("Property: random trees with joint limits end within them, rigid and connected",
          "[joints][property]") {
  std::mt19937_64 rng(20261122);
  int solves = 0, jumps = 0;
  for (int trial = 0; trial < 80; ++trial) {
    const auto m = std::make_shared<const Model>(random_joint_model(rng, 2 + trial % 10));
    // Targets on a random subset of points: where an in-range motion puts
    // them, plus an offset that makes some of them unreachable.
    std::uniform_int_distribution<int> coin(0, 2), level(0, 2);
    std::uniform_real_distribution<double> weight(0.5, 2.0), offset(-0.3, 0.3);
    std::vector<Target> targets;
    for (int p = 0; p < static_cast<int>(m->points.size()); ++p)
      if (m->points[p].kind != PointKind::base && coin(rng) == 0)
        targets.push_back({p, level(rng), weight(rng)});
    if (targets.empty()) targets.push_back({static_cast<int>(m->points.size()) - 1, 0, 1.0});
    MotionSettings ms;
    ms.seed = static_cast<unsigned>(trial);
    ms.max_swing_rad = 1.5;
    SyntheticMotion motion(*m, ms);
    Posture goal = Posture::rest(*m);
    motion.posture_at(0.37 * trial, goal);
    REQUIRE(max_limit_excess_rad(*m, goal) < 1e-9);  // the motion itself keeps the limits
    std::vector<Eigen::Vector3d> pos;
    for (const Target& t : targets)
      pos.push_back(goal.point_world_m(*m, t.point) +
                    (trial % 2 ? draw_vector3(offset, rng) : Eigen::Vector3d::Zero()));
    const auto visible = all_visible(targets.size());
    auto some_hidden = visible;  // a third frame with every third target hidden
    for (std::size_t i = 0; i + 1 < some_hidden.size(); i += 3) some_hidden[i] = 0;
    for (SegmentFit fit : {SegmentFit::paper, SegmentFit::rigid})
      for (RootMode root : {RootMode::fixed, RootMode::free})
        for (bool prio : {false, true}) {
          SolverOptions o;
          o.segment_fit = fit;
          o.root = root;
          o.use_priorities = prio;
          o.max_iterations = 100;
          o.tolerance_m = 1e-6;
          o.stall_tolerance_m = 1e-7;
          o.subtree_carry = trial % 3 == 0 ? 0.5 : 0.0;
          // Weak anchors too: the riders of a stronger level's pass are then turned far.
          o.anchor_weight = trial % 4 == 1 ? 1.0 : trial % 4 == 3 ? 0.0 : 1000.0;
          FabrikSolver solver(m, targets, o);
          Posture posture = Posture::rest(*m);
          for (int frame = 0; frame < 3; ++frame) {  // cold, warm, warm with targets hidden
            const SolveResult r = solver.solve(pos, frame < 2 ? visible : some_hidden, posture);
            ++solves;
            jumps += r.jumps;
            CAPTURE(trial, frame, m->segments.size(), targets.size(), static_cast<int>(fit),
                    static_cast<int>(root), prio, to_string(r.status));
            REQUIRE(max_limit_excess_rad(*m, posture) < 1e-9);
            REQUIRE(max_hinge_plane_m(*m, posture) < 1e-9);
            REQUIRE(max_rigidity_error(*m, posture) < 1e-9);
            REQUIRE(max_joint_gap_m(*m, posture) < 1e-9);
            for (std::size_t i = 0; i < targets.size(); ++i)
              if (frame < 2)
                REQUIRE(std::abs(solver.target_distances_m()[i] -
                                 (posture.point_world_m(*m, targets[i].point) - pos[i]).norm()) <
                        1e-9);
          }
        }
  }
  CHECK(solves == 80 * 8 * 3);
  CHECK(jumps > 0);  // the extrapolation (one level, no priorities) took part
}

TEST_CASE(
    "A start posture outside the ranges ends within them and joined, also where no target pulls",
    "[joints][property]") {
  // Segments without a target in a pass ride on their parent with the
  // relative rotation they started with: the solve must bring a start that
  // is out of range within range before any of them rides.
  std::mt19937_64 rng(424242);
  for (int trial = 0; trial < 40; ++trial) {
    const auto m = std::make_shared<const Model>(random_joint_model(rng, 3 + trial % 8));
    std::vector<Target> targets;
    for (int p = 0; p < static_cast<int>(m->points.size()); ++p)
      if (m->points[p].segment == 0 && m->points[p].kind != PointKind::base)
        targets.push_back({p, 0, 1.0});
    if (targets.empty()) targets.push_back({0, 0, 1.0});
    Posture posture = Posture::rest(*m);
    for (SegmentPose& pose : posture.segments)
      pose.set_rotation(Eigen::Quaterniond(random_rotation(rng)));
    // Rigid segments at random rotations, joined again (a scrambled warm start).
    for (int s = 1; s < static_cast<int>(m->segments.size()); ++s)
      posture.segments[s].base_world_m = posture.point_world_m(*m, m->segments[s].parent_point);
    REQUIRE(max_limit_excess_rad(*m, posture) > 1e-3);  // the start is out of range
    std::vector<Eigen::Vector3d> pos;
    for (const Target& t : targets) pos.push_back(posture.point_world_m(*m, t.point));
    SolverOptions o;
    o.root = RootMode::free;
    FabrikSolver solver(m, targets, o);
    CAPTURE(trial, m->segments.size());
    // With no target visible no pass runs: the start alone must come out within range, and
    // joined again where it came apart.
    const std::vector<std::uint8_t> none(targets.size(), 0);
    Posture unseen = posture;
    for (int s = 1; s < static_cast<int>(m->segments.size()); ++s)
      unseen.segments[s].base_world_m += Eigen::Vector3d(0.01 * s, 0.0, -0.02);
    REQUIRE(max_joint_gap_m(*m, unseen) > 0.005);
    CHECK(solver.solve(pos, none, unseen).iterations == 0);
    CHECK(max_limit_excess_rad(*m, unseen) < 1e-9);
    CHECK(max_joint_gap_m(*m, unseen) < 1e-12);
    solver.solve(pos, all_visible(targets.size()), posture);
    CHECK(max_limit_excess_rad(*m, posture) < 1e-9);
    CHECK(max_rigidity_error(*m, posture) < 1e-9);
    CHECK(max_joint_gap_m(*m, posture) < 1e-9);
    // A posture a solve left is joined to rounding: a solve with nothing visible leaves it as
    // it is, to the bit.
    const Posture solved = posture;
    solver.solve(pos, none, posture);
    for (std::size_t s = 0; s < m->segments.size(); ++s) {
      CHECK(posture.segments[s].base_world_m == solved.segments[s].base_world_m);
      CHECK(posture.segments[s].q_world.coeffs() == solved.segments[s].q_world.coeffs());
    }
  }
}

TEST_CASE("Limited joints reach reachable targets within range", "[joints]") {
  // Targets where an in-range motion puts every marker of the full-body model:
  // the limited solver tracks them as closely as the free one.
  const Model body = test::fullbody_model();
  // The full-body model with a knee, elbow hinges and ball hips and shoulders.
  auto limited = [&] {
    std::vector<SegmentSpec> out;
    for (const Segment& seg : body.segments) {
      SegmentSpec s;
      s.name = seg.name;
      s.parent = seg.parent < 0 ? "" : body.segments[seg.parent].name;
      s.base = body.points[seg.base_point].name;
      for (int i = seg.first_point + 1; i < seg.first_point + seg.point_count; ++i)
        s.points.push_back({body.points[i].name, body.points[i].p_local_m,
                            body.points[i].kind == PointKind::marker});
      const auto ends = [&](const char* suffix) {
        return s.name.size() > std::strlen(suffix) &&
               s.name.compare(s.name.size() - std::strlen(suffix), std::strlen(suffix), suffix) ==
                   0;
      };
      if (ends("shank")) {
        s.joint.type = JointType::hinge;
        s.joint.min_rad[0] = -140 * kDeg;
        s.joint.max_rad[0] = 5 * kDeg;
      } else if (ends("forearm")) {
        s.joint.type = JointType::hinge;
        s.joint.min_rad[0] = 0.0;
        s.joint.max_rad[0] = 150 * kDeg;
      } else if (ends("thigh") || ends("upper_arm")) {
        s.joint.type = JointType::ball;
        s.joint.min_rad = {-40 * kDeg, -40 * kDeg, -40 * kDeg};
        s.joint.max_rad = {120 * kDeg, 40 * kDeg, 40 * kDeg};
      }
      out.push_back(s);
    }
    return out;
  }();
  const auto m = std::make_shared<const Model>(build_model("limited", limited, body.root_rest_m));
  const std::vector<int> points = m->marker_points();
  std::vector<Target> targets;
  for (int p : points) targets.push_back({p, 0, 1.0});
  FabrikSolver solver(m, targets, tight_options(1e-5, RootMode::free));
  MotionSettings ms;
  ms.seed = 5;
  SyntheticMotion motion(*m, ms);
  Posture truth = Posture::rest(*m), posture = Posture::rest(*m);
  std::vector<Eigen::Vector3d> pos(points.size());
  double worst_m = 0.0;
  for (int f = 0; f < 100; ++f) {
    motion.posture_at(0.02 * f, truth);
    motion.sample(truth, points, 0.0, pos);
    const SolveResult r = solver.solve(pos, all_visible(pos.size()), posture);
    if (f > 0) worst_m = std::max(worst_m, r.max_m);
    REQUIRE(max_limit_excess_rad(*m, posture) < 1e-9);
  }
  CAPTURE(worst_m);
  CHECK(worst_m < 1e-3);
}

TEST_CASE("A target moving across a hinge limit gives a continuous angle, also from behind",
          "[joints][flips]") {
  // An upper arm held by two strong targets and a forearm on a hinge about z
  // with a range of 0 to 120 degrees. The wrist's target goes once around the
  // elbow, 1 degree a frame, slightly out of the hinge's plane: the angle must
  // follow it into range, stop at the bound it reaches, and stay there while
  // the target goes round behind (never jump to the other bound).
  std::vector<SegmentSpec> specs(2);
  specs[0] = {"upper",
              "",
              "shoulder",
              {{"elbow", {0, -0.30, 0}, false}, {"m_upper", {0.05, -0.15, 0.0}, true}},
              Eigen::Matrix3d::Identity(),
              {}};
  specs[1] = {"forearm", "upper", "elbow", {{"wrist", {0, -0.25, 0}, false}},
              Eigen::Matrix3d::Identity(), {}};
  specs[1].joint.type = JointType::hinge;
  specs[1].joint.min_rad[0] = 0.0;
  specs[1].joint.max_rad[0] = 120 * kDeg;
  const auto m = std::make_shared<const Model>(build_model("arm", specs, Eigen::Vector3d::Zero()));
  const int elbow = m->find_point("elbow"), wrist = m->find_point("wrist");
  const int upper_marker = m->find_point("m_upper");
  const Posture rest = Posture::rest(*m);
  // The default anchors and weaker ones: the weak pass turns the upper arm more, the strong
  // pass turns it back, and the forearm, a rider there, must stay on its bound (keeping its
  // world rotation it left the bound by up to 0.07 degrees at 1000 and 6.5 at 10, where it
  // then jumped to the other bound at 285).
  for (const double anchor : {1000.0, 100.0, 10.0}) {
    CAPTURE(anchor);
    SolverOptions o = tight_options(1e-6);
    o.anchor_weight = anchor;
    FabrikSolver solver(m, {{upper_marker, 1, 1.0}, {elbow, 1, 1.0}, {wrist, 0, 1.0}}, o);
    Posture posture = rest;
    double previous_deg = NAN;
    double biggest_step_deg = 0.0;
    for (int phi_deg = -60; phi_deg <= 290; ++phi_deg) {
      const double phi = phi_deg * kDeg;
      const Eigen::Vector3d elbow_m = rest.point_world_m(*m, elbow);
      const std::vector<Eigen::Vector3d> pos{
          rest.point_world_m(*m, upper_marker), elbow_m,
          elbow_m + Eigen::Vector3d(0.25 * std::sin(phi), -0.25 * std::cos(phi), 0.01)};
      solver.solve(pos, all_visible(3), posture);
      const double angle_deg = joint_angles_rad(*m, posture, 1)[0] / kDeg;
      CAPTURE(phi_deg, angle_deg, previous_deg);
      REQUIRE(max_limit_excess_rad(*m, posture) < 1e-9);
      // Where the target is in range, the angle is the target's, within the anchors' give
      // (the target is 1 cm off the hinge's plane): 0.00024, 0.0024 and 0.022 degrees.
      if (phi_deg >= 1 && phi_deg <= 119) REQUIRE(std::abs(angle_deg - phi_deg) < 1.0 / anchor);
      // Behind the arm (past 120, up to 290 = -70), it stays at the bound it left through.
      if (phi_deg >= 120) REQUIRE(std::abs(angle_deg - 120.0) < 1e-6);
      if (!std::isnan(previous_deg))
        biggest_step_deg = std::max(biggest_step_deg, std::abs(angle_deg - previous_deg));
      previous_deg = angle_deg;
    }
    CHECK(biggest_step_deg <= 1.0 + 1e-3);
  }
}

TEST_CASE("A target moving across a ball joint's range gives continuous angles",
          "[joints][flips]") {
  // A ball joint limited to +-45 degrees about z, +-30 about x and +-20 about
  // y, whose child has three markers that fix its orientation; the targets
  // turn the child from -90 to +90 degrees about z and back, tilted about x.
  std::vector<SegmentSpec> specs(2);
  specs[0].name = "base";
  specs[0].base = "root";
  specs[0].points = {
      {"hip", {0, -0.10, 0}, false}, {"m0", {0.1, 0, 0}, true}, {"m1", {0, 0, 0.1}, true}};
  specs[1].name = "leg";
  specs[1].parent = "base";
  specs[1].base = "hip";
  specs[1].points = {{"foot", {0, -0.4, 0}, false},
                     {"toe", {0.15, -0.4, 0}, true},
                     {"side", {0, -0.2, 0.1}, true}};
  specs[1].joint.type = JointType::ball;
  specs[1].joint.min_rad = {-45 * kDeg, -30 * kDeg, -20 * kDeg};
  specs[1].joint.max_rad = {45 * kDeg, 30 * kDeg, 20 * kDeg};
  const auto m = std::make_shared<const Model>(build_model("leg", specs, Eigen::Vector3d::Zero()));
  const Posture rest = Posture::rest(*m);
  const std::vector<int> points{m->find_point("m0"), m->find_point("m1"), m->find_point("foot"),
                                m->find_point("toe"), m->find_point("side")};
  const SolverOptions o = tight_options(1e-6);
  FabrikSolver solver(m,
                      {{points[0], 1, 1.0},
                       {points[1], 1, 1.0},
                       {points[2], 0, 1.0},
                       {points[3], 0, 1.0},
                       {points[4], 0, 1.0}},
                      o);
  Posture posture = rest;
  Eigen::Vector3d previous = Eigen::Vector3d::Constant(NAN);
  Eigen::Quaterniond previous_q = Eigen::Quaterniond::Identity();
  double biggest_step_deg = 0.0, biggest_turn_deg = 0.0;
  const Eigen::Vector3d hip_m = rest.point_world_m(*m, m->find_point("hip"));
  for (int k = 0; k <= 360; ++k) {
    const double z = (k <= 180 ? -90 + k : 270 - k) * kDeg, x = 10 * kDeg * std::sin(k * kDeg);
    const Eigen::Matrix3d r = rotation_zxy(Eigen::Vector3d(z, x, 0.0));
    std::vector<Eigen::Vector3d> pos;
    for (int i = 0; i < 5; ++i) {
      const Eigen::Vector3d p = rest.point_world_m(*m, points[i]);
      pos.push_back(i < 2 ? p : Eigen::Vector3d(hip_m + r * (p - hip_m)));
    }
    solver.solve(pos, all_visible(5), posture);
    const Eigen::Vector3d a = joint_angles_rad(*m, posture, 1);
    CAPTURE(k, a / kDeg);
    REQUIRE(max_limit_excess_rad(*m, posture) < 1e-9);
    if (std::abs(z) < 44 * kDeg) REQUIRE((a - Eigen::Vector3d(z, x, 0)).norm() < 0.01 * kDeg);
    const Eigen::Quaterniond q = posture.segments[1].q_world;
    if (!std::isnan(previous[0])) {
      biggest_step_deg = std::max(biggest_step_deg, (a - previous).cwiseAbs().maxCoeff() / kDeg);
      biggest_turn_deg = std::max(biggest_turn_deg, q.angularDistance(previous_q) / kDeg);
    }
    previous = a;
    previous_q = q;
  }
  CAPTURE(biggest_step_deg, biggest_turn_deg);
  // The targets turn about 1 degree a frame. Where z is held at its bound the
  // best fit trades the missing z for twist, and that optimum itself moves
  // faster than the targets: up to 2.6 degrees a frame here (the same figures
  // as a bounded quasi-Newton minimisation of the same problem, scipy's
  // L-BFGS-B, gives frame by frame). No angle jumps.
  CHECK(biggest_turn_deg <= 3.0);
  CHECK(biggest_step_deg <= 3.0);
}

TEST_CASE("Jacobian baselines keep the same joints", "[joints][jacobian]") {
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 20; ++trial) {
    const auto m = std::make_shared<const Model>(random_joint_model(rng, 3 + trial % 5));
    std::vector<Target> targets;
    for (int p = 0; p < static_cast<int>(m->points.size()); ++p)
      if (m->points[p].kind != PointKind::base) targets.push_back({p, 0, 1.0});
    std::uniform_real_distribution<double> u(-0.5, 0.5);
    std::vector<Eigen::Vector3d> pos;
    for (std::size_t i = 0; i < targets.size(); ++i) pos.push_back(draw_vector3(u, rng));
    for (JacobianMethod method :
         {JacobianMethod::transpose, JacobianMethod::damped_least_squares}) {
      SolverOptions o;
      o.max_iterations = 200;
      JacobianSolver solver(m, targets, o, {method, 0.05, 0.2});
      Posture posture = Posture::rest(*m);
      solver.solve(pos, all_visible(pos.size()), posture);
      CAPTURE(trial, static_cast<int>(method));
      REQUIRE(max_limit_excess_rad(*m, posture) < 1e-9);
      REQUIRE(max_hinge_plane_m(*m, posture) < 1e-9);
      REQUIRE(max_rigidity_error(*m, posture) < 1e-9);
    }
  }
}

TEST_CASE("Solvers refuse inputs of the wrong size with a status, not a read past the end",
          "[fabrik][jacobian]") {
  const Model m = test::paper_model();
  const std::vector<Target> targets{{m.find_point("r_wrist"), 1, 1.0},
                                    {m.find_point("l_wrist"), 0, 1.0}};
  const std::vector<Eigen::Vector3d> one{{0.5, 0.5, 0.3}};
  const std::vector<Eigen::Vector3d> two{{0.5, 0.5, 0.3}, {-0.5, 0.5, 0.3}};
  FabrikSolver fabrik(m, targets, {});
  JacobianSolver jt(m, targets, {});
  Posture posture = Posture::rest(m);
  const Posture before = posture;
  CHECK(fabrik.solve(one, all_visible(2), posture).status == SolveStatus::size_mismatch);
  CHECK(fabrik.solve(two, all_visible(1), posture).status == SolveStatus::size_mismatch);
  CHECK(jt.solve(one, all_visible(2), posture).status == SolveStatus::size_mismatch);
  CHECK(jt.solve(two, all_visible(3), posture).status == SolveStatus::size_mismatch);
  Posture short_posture;
  CHECK(fabrik.solve(two, all_visible(2), short_posture).status == SolveStatus::size_mismatch);
  for (std::size_t s = 0; s < posture.segments.size(); ++s)
    CHECK(posture.segments[s].base_world_m == before.segments[s].base_world_m);
  CHECK(fabrik.solve(two, all_visible(2), posture).status != SolveStatus::size_mismatch);
}

TEST_CASE("Subtree carry: a hinged child's targets turn its parent about its long axis",
          "[joints][carry]") {
  // An upper arm whose only marker lies on its long axis, and a forearm on a
  // hinge with two wrist markers. The goal turns the upper arm 60 deg about
  // its axis and flexes the elbow further: reachable exactly, but only if
  // the forearm's markers turn the upper arm, which its joint point cannot.
  const test::HingedArm arm = test::hinged_arm();
  const auto& m = arm.model;
  const std::vector<Target>& targets = arm.targets;
  const std::vector<Eigen::Vector3d>& pos = arm.goal_m;
  struct Outcome {
    double max_m, twist_rad;  // worst target distance; the upper arm's turn about its axis
  };
  auto solve_with = [&](double carry, double fallback_carry) {
    SolverOptions o;
    o.segment_fit = SegmentFit::rigid;
    o.max_iterations = 400;
    o.tolerance_m = 1e-6;
    o.stall_tolerance_m = 1e-10;
    o.subtree_carry = carry;
    o.fallback_carry = fallback_carry;
    FabrikSolver solver(m, targets, o);
    Posture posture = arm.start;
    const SolveResult r = solver.solve(pos, all_visible(targets.size()), posture);
    CHECK(max_limit_excess_rad(*m, posture) < 1e-9);
    CHECK(max_hinge_plane_m(*m, posture) < 1e-9);
    CHECK(max_rigidity_error(*m, posture) < 1e-9);
    const Eigen::Quaterniond& q = posture.segments[1].q_world;
    return Outcome{r.max_m, 2.0 * std::atan2(q.y(), q.w())};
  };
  const Outcome without = solve_with(0.0, 0.0), with = solve_with(0.5, 0.0);
  // The default: no carry until the loop climbs away from its lowest RMS.
  const Outcome fallback = solve_with(0.0, SolverOptions{}.fallback_carry);
  CAPTURE(without.max_m, with.max_m, fallback.max_m, without.twist_rad / kDeg,
          with.twist_rad / kDeg, fallback.twist_rad / kDeg);
  // FABRIK's own fixed point: the upper arm never turns, the wrist stays far.
  CHECK(without.max_m > 0.05);
  CHECK(std::abs(without.twist_rad) < 10.0 * kDeg);
  // Carried, the wrist markers turn it (the loop approaches the exact fit
  // slowly, as coordinate descent does along a valley: 2 mm in 4000 iterations).
  CHECK(with.max_m < 0.1 * without.max_m);
  CHECK(std::abs(with.twist_rad - 60.0 * kDeg) < 5.0 * kDeg);
  // Climbing from 51 to 65 mm RMS on the way to that fixed point, the loop takes the carry.
  CHECK(fallback.max_m < 0.1 * without.max_m);
  CHECK(std::abs(fallback.twist_rad - 60.0 * kDeg) < 5.0 * kDeg);
}

TEST_CASE("A rider some level pulls keeps its world rotation where its parent turns, within range",
          "[joints][priority]") {
  // A trunk on a fixed root whose three markers (level 1) are turned 30 deg about z, and a limb
  // hanging from it whose two markers (level 0) already sit on their targets. One
  // iteration: the weak pass finds nothing to do, and in the strong pass the limb is a rider the
  // weak level pulls on. Known answer: the limb keeps its world rotation where its joint
  // allows; a ball joint's a_z, beyond its range, comes to the bound it left through (-10 deg,
  // here also the nearer one), its other angles kept; a hinge comes to that bound.
  auto spec = [](const char* name, const char* parent, const char* base,
                 std::vector<PointSpec> points, JointType type) {
    SegmentSpec s;
    s.name = name;
    s.parent = parent;
    s.base = base;
    s.points = std::move(points);
    s.joint.type = type;
    s.joint.min_rad = {-10 * kDeg, -20 * kDeg, -20 * kDeg};
    s.joint.max_rad = {10 * kDeg, 20 * kDeg, 20 * kDeg};
    return s;
  };
  for (JointType type : {JointType::free, JointType::ball, JointType::hinge}) {
    const auto m = std::make_shared<const Model>(
        build_model("rider",
                    {spec("trunk", "", "root",
                          {{"hip", {0, -0.05, 0}, false},
                           {"T1", {0.2, 0, 0}, true},
                           {"T2", {0, 0.2, 0}, true},
                           {"T3", {0, 0, 0.2}, true}},
                          JointType::free),
                     spec("limb", "trunk", "hip",
                          {{"L1", {0, -0.4, 0}, true}, {"L2", {0.05, -0.4, 0}, true}}, type)},
                    Eigen::Vector3d::Zero()));
    const Eigen::Quaterniond turn(Eigen::AngleAxisd(30 * kDeg, Eigen::Vector3d::UnitZ()));
    std::vector<Target> targets;
    std::vector<Eigen::Vector3d> pos;
    const Posture start = Posture::rest(*m);
    for (int p : m->marker_points()) {
      const bool on_trunk = m->points[p].segment == 0;
      targets.push_back({p, on_trunk ? 1 : 0, 1.0});
      const Eigen::Vector3d at_m = start.point_world_m(*m, p);
      pos.push_back(on_trunk ? Eigen::Vector3d(turn * at_m) : at_m);
    }
    SolverOptions o;
    o.root = RootMode::fixed;
    o.anchor_weight = 0.0;
    o.max_iterations = 1;
    o.level_passes = 1;
    FabrikSolver solver(m, targets, o);
    Posture p = start;
    const SolveResult r = solver.solve(pos, all_visible(targets.size()), p);
    CAPTURE(static_cast<int>(type), r.passes);
    const Eigen::Quaterniond& q_trunk = p.segments[0].q_world;
    REQUIRE(q_trunk.angularDistance(Eigen::Quaterniond::Identity()) > 20 * kDeg);  // it turned
    // The limb's angles if it kept its world rotation (the anatomical frames are the world's).
    Eigen::Vector3d kept_rad =
        cardan_zxy((q_trunk.conjugate() * start.segments[1].q_world).toRotationMatrix());
    REQUIRE(kept_rad[0] < -20 * kDeg);  // beyond a_z's range
    REQUIRE(std::abs(kept_rad[1]) < 19 * kDeg);
    REQUIRE(std::abs(kept_rad[2]) < 19 * kDeg);
    if (type != JointType::free) kept_rad[0] = -10 * kDeg;
    if (type == JointType::hinge) kept_rad[1] = kept_rad[2] = 0.0;
    const Eigen::Quaterniond expected = q_trunk * Eigen::Quaterniond(rotation_zxy(kept_rad));
    CHECK(p.segments[1].q_world.angularDistance(expected) < 1e-12);
    CHECK((p.segments[1].base_world_m - p.point_world_m(*m, m->segments[1].parent_point)).norm() <
          1e-15);
  }
}

TEST_CASE(
    "A solve's start: a base up to 1 nm off its joint is left as it is, one further goes onto it",
    "[joints]") {
  // Known answer of prepare_start's threshold: nothing visible, so no pass moves a base.
  const Model m = test::chain_model(4, 0.2);
  FabrikSolver solver(m, {{m.find_point("j4"), 0, 1.0}}, SolverOptions{});
  const std::vector<Eigen::Vector3d> target{{0.1, 0.5, 0.2}};
  for (const double off_m : {0.5e-9, 2e-9, 0.05}) {
    CAPTURE(off_m);
    Posture p = Posture::rest(m);
    const Eigen::Vector3d moved_m = p.segments[2].base_world_m + Eigen::Vector3d(off_m, 0.0, 0.0);
    p.segments[2].base_world_m = moved_m;
    solver.solve(target, std::vector<std::uint8_t>{0}, p);
    const Eigen::Vector3d joint_m = p.point_world_m(m, m.segments[2].parent_point);
    if (off_m < 1e-9)
      CHECK(p.segments[2].base_world_m == moved_m);
    else
      CHECK(p.segments[2].base_world_m == joint_m);
  }
}
