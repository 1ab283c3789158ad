// Solver behaviour: geometry, reaching, priorities, warm start, baselines.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include <string>
#include "solver/fabrik_solver.hpp"
#include "solver/jacobian_solver.hpp"
#include "solver/rotation_fit.hpp"
#include "synth/random_draws.hpp"
#include "synth/synthetic_motion.hpp"
#include "test_models.hpp"

using namespace fabrik;
using fabrik::test::max_joint_gap_m;
using fabrik::test::max_rigidity_error;

namespace {

constexpr double kRigidRel = 1e-9;

std::vector<std::uint8_t> all_visible(std::size_t n) {
  return std::vector<std::uint8_t>(n, 1);
}

double chain_length_m(const Model& m) {
  double len = 0.0;
  for (const Point& p : m.points)
    if (p.kind != PointKind::base) len += p.p_local_m.norm();
  return len;
}

// Perpendicular distance of point p from the line through a with direction u.
double off_line_m(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& u) {
  const Eigen::Vector3d v = p - a;
  return (v - v.dot(u) * u).norm();
}

SolverOptions options_for(SegmentFit fit, RootMode root = RootMode::fixed) {
  SolverOptions o;
  o.segment_fit = fit;
  o.root = root;
  o.tolerance_m = 1e-4;
  o.max_iterations = 500;
  o.stall_tolerance_m = 1e-10;
  return o;
}

}  // namespace

TEST_CASE("FABRIK reaches a reachable chain target and keeps segments rigid", "[fabrik]") {
  const Model m = test::chain_model(6, 0.2);
  for (SegmentFit fit : {SegmentFit::paper, SegmentFit::rigid}) {
    CAPTURE(static_cast<int>(fit));
    FabrikSolver solver(m, {{m.find_point("j6"), 0, 1.0}}, options_for(fit));
    Posture posture = Posture::rest(m);
    const std::vector<Eigen::Vector3d> target{{0.5, 0.6, 0.3}};
    const SolveResult r = solver.solve(target, all_visible(1), posture);
    CHECK(r.status == SolveStatus::converged);
    CHECK(r.max_m <= 1e-4);
    CHECK(max_rigidity_error(m, posture) < kRigidRel);
    CHECK(max_joint_gap_m(m, posture) < 1e-12);
    CHECK((posture.segments[0].base_world_m - m.root_rest_m).norm() < 1e-15);  // root pinned
  }
}

TEST_CASE("An unreachable target leaves the chain straight towards it", "[fabrik]") {
  const Model m = test::chain_model(5, 0.2);
  for (SegmentFit fit : {SegmentFit::paper, SegmentFit::rigid}) {
    FabrikSolver solver(m, {{m.find_point("j5"), 0, 1.0}}, options_for(fit));
    Posture posture = Posture::rest(m);
    const Eigen::Vector3d target(1.5, 0.4, -0.9);
    const SolveResult r =
        solver.solve(std::vector<Eigen::Vector3d>{target}, all_visible(1), posture);
    CHECK(r.status != SolveStatus::converged);
    const Eigen::Vector3d u = target.normalized();
    for (int s = 0; s < 5; ++s)
      CHECK(off_line_m(posture.segments[s].base_world_m, {0, 0, 0}, u) < 1e-5);
    CHECK(r.max_m == Approx(target.norm() - chain_length_m(m)).margin(1e-6));
    CHECK(max_rigidity_error(m, posture) < kRigidRel);
  }
}

TEST_CASE("Subbase segments keep their shape under every option", "[fabrik][subbase]") {
  const Model m = test::paper_model();
  const std::vector<Target> targets{{m.find_point("r_wrist"), 1, 1.0},
                                    {m.find_point("l_wrist"), 0, 1.0}};
  const std::vector<Eigen::Vector3d> pos{{0.6, 0.5, 0.4}, {-0.3, 0.9, 0.3}};
  for (SegmentFit fit : {SegmentFit::paper, SegmentFit::rigid})
    for (bool prio : {false, true})
      for (RootMode root : {RootMode::fixed, RootMode::free}) {
        SolverOptions o = options_for(fit, root);
        o.use_priorities = prio;
        FabrikSolver solver(m, targets, o);
        Posture posture = Posture::rest(m);
        solver.solve(pos, all_visible(2), posture);
        CAPTURE(static_cast<int>(fit), prio, static_cast<int>(root));
        CHECK(max_rigidity_error(m, posture) < kRigidRel);
        CHECK(max_joint_gap_m(m, posture) < 1e-12);
        // Both wrists are reachable together here.
        CHECK(solver.target_distances_m()[0] < 2e-3);
        CHECK(solver.target_distances_m()[1] < 2e-3);
      }
}

TEST_CASE("Priorities: the strongest level does no worse than alone, within tolerance",
          "[fabrik][priority]") {
  const Model m = test::paper_model();
  const int rw = m.find_point("r_wrist"), lw = m.find_point("l_wrist");
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.6, 1.6);
  for (int trial = 0; trial < 50; ++trial) {
    const std::vector<Eigen::Vector3d> pos{{u(rng), u(rng), u(rng)}, {u(rng), u(rng), u(rng)}};
    SolverOptions o = options_for(SegmentFit::paper);
    o.tolerance_m = 1e-3;
    FabrikSolver alone(m, {{rw, 1, 1.0}}, o);
    Posture p_alone = Posture::rest(m);
    alone.solve(std::vector<Eigen::Vector3d>{pos[0]}, all_visible(1), p_alone);
    FabrikSolver both(m, {{rw, 1, 1.0}, {lw, 0, 1.0}}, o);
    Posture p_both = Posture::rest(m);
    both.solve(pos, all_visible(2), p_both);
    CAPTURE(trial, pos[0].transpose(), pos[1].transpose());
    CHECK(both.target_distances_m()[0] <= alone.target_distances_m()[0] + o.tolerance_m);
  }
}

TEST_CASE("Without priorities a symmetric conflict is balanced, with them the strong side wins",
          "[fabrik][priority]") {
  const Model m = test::paper_model();
  const std::vector<Eigen::Vector3d> pos{{1.0, 0.9, 0.6}, {-1.0, 0.9, 0.6}};
  const std::vector<Target> targets{{m.find_point("r_wrist"), 1, 1.0},
                                    {m.find_point("l_wrist"), 0, 1.0}};
  SolverOptions o = options_for(SegmentFit::paper);
  o.use_priorities = false;
  FabrikSolver flat(m, targets, o);
  Posture p = Posture::rest(m);
  flat.solve(pos, all_visible(2), p);
  const double r_flat = flat.target_distances_m()[0], l_flat = flat.target_distances_m()[1];
  CHECK(std::abs(r_flat - l_flat) < 1e-3);
  o.use_priorities = true;
  FabrikSolver prio(m, targets, o);
  Posture q = Posture::rest(m);
  prio.solve(pos, all_visible(2), q);
  CHECK(prio.target_distances_m()[0] < r_flat - 0.05);  // the strong wrist gets much closer
  CHECK(prio.target_distances_m()[1] > l_flat + 0.05);  // at the weak one's expense
}

TEST_CASE("The paper's literal priority loop runs the weakest level first", "[fabrik][priority]") {
  // Each level pulls alone (no anchors) and once per iteration (no revisits):
  // the order of the loop alone decides which target ends closer. Weakest
  // first, the strong wrist ends closer than the weak one; the other way
  // round it would be the weak one.
  const Model m = test::paper_model();
  const std::vector<Eigen::Vector3d> pos{{1.0, 0.9, 0.6}, {-1.0, 0.9, 0.6}};
  const std::vector<Target> targets{{m.find_point("r_wrist"), 1, 1.0},
                                    {m.find_point("l_wrist"), 0, 1.0}};
  for (SegmentFit fit : {SegmentFit::paper, SegmentFit::rigid}) {
    SolverOptions o = options_for(fit);
    o.anchor_weight = 0.0;
    o.level_passes = 1;
    FabrikSolver solver(m, targets, o);
    Posture p = Posture::rest(m);
    solver.solve(pos, all_visible(2), p);
    const double strong_m = solver.target_distances_m()[0], weak_m = solver.target_distances_m()[1];
    CAPTURE(static_cast<int>(fit), strong_m, weak_m);
    INFO(
        "the strong (level 1) wrist must end clearly closer than the weak one: the loop must "
        "visit the weakest level first");
    CHECK(strong_m < weak_m - 0.05);
  }
}

TEST_CASE("A segment no level pulls ends on its parent's joint, turned with it as it started",
          "[fabrik][priority]") {
  // Pelvis markers at level 1, leg markers at level 0: the trunk, arms and head ride in
  // every pass, and the strongest level is revisited (level_passes 8). Known answer: each
  // rider's rotation relative to its parent is the start's, its base on the parent's joint.
  const Model m = test::fullbody_model();
  std::vector<Target> targets;
  for (int p : m.marker_points()) {
    const std::string& seg = m.segments[m.points[p].segment].name;
    if (seg == "pelvis") targets.push_back({p, 1, 1.0});
    if (seg.find("shank") != std::string::npos || seg.find("foot") != std::string::npos)
      targets.push_back({p, 0, 1.0});
  }
  MotionSettings ms;
  ms.seed = 4;
  SyntheticMotion motion(m, ms);
  Posture start = Posture::rest(m), truth = Posture::rest(m);
  motion.posture_at(0.2, start);
  motion.posture_at(0.7, truth);
  std::vector<Eigen::Vector3d> pos;
  for (const Target& t : targets)
    pos.push_back(truth.point_world_m(m, t.point) + Eigen::Vector3d(0.3, 0.0, 0.1));
  for (RootMode root : {RootMode::free, RootMode::fixed}) {
    SolverOptions o = options_for(SegmentFit::rigid, root);
    o.level_passes = 8;
    FabrikSolver solver(m, targets, o);
    Posture p = start;
    const SolveResult r = solver.solve(pos, all_visible(targets.size()), p);
    CAPTURE(static_cast<int>(root), r.passes, r.iterations);
    REQUIRE(r.passes > 2 * r.iterations);  // the strongest level was revisited
    int riders = 0;
    for (std::size_t s = 1; s < m.segments.size(); ++s) {
      const std::string& name = m.segments[s].name;
      if (name == "pelvis" || name.find("thigh") != std::string::npos ||
          name.find("shank") != std::string::npos || name.find("foot") != std::string::npos)
        continue;
      ++riders;
      CAPTURE(name);
      const int parent = m.segments[s].parent;
      const Eigen::Quaterniond rel_start =
          start.segments[parent].q_world.conjugate() * start.segments[s].q_world;
      const Eigen::Quaterniond rel_end =
          p.segments[parent].q_world.conjugate() * p.segments[s].q_world;
      CHECK(rel_end.angularDistance(rel_start) < 1e-9);
      CHECK((p.segments[s].base_world_m - p.point_world_m(m, m.segments[s].parent_point)).norm() <
            1e-12);
    }
    CHECK(riders >= 5);  // trunk, head and arms
  }
}

TEST_CASE("Anchors: a weak level costs the strongest one nothing", "[fabrik][priority]") {
  // Random conflicting targets on the full-body model: markers of the pelvis
  // and thighs at level 1 where a motion puts them, and markers of the legs
  // at level 0 pulled elsewhere. With stronger levels taking part in the weak
  // level's pass (anchor_weight), the strong level ends as close as it does
  // alone; without them it would give way to the weak one.
  const Model m = test::fullbody_model();
  std::vector<Target> strong, both;
  for (int p : m.marker_points()) {
    const std::string& seg = m.segments[m.points[p].segment].name;
    const bool is_strong = seg == "pelvis" || seg.find("thigh") != std::string::npos;
    const bool is_weak =
        seg.find("shank") != std::string::npos || seg.find("foot") != std::string::npos;
    if (is_strong) strong.push_back({p, 1, 1.0});
    if (is_strong || is_weak) both.push_back({p, is_strong ? 1 : 0, 1.0});
  }
  MotionSettings ms;
  ms.seed = 9;
  SyntheticMotion motion(m, ms);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-0.15, 0.15);
  double worst_excess_m = 0.0;
  for (int trial = 0; trial < 20; ++trial) {
    Posture truth = Posture::rest(m);
    motion.posture_at(0.31 * trial, truth);
    std::vector<Eigen::Vector3d> pos_strong, pos_both;
    for (const Target& t : both) {
      Eigen::Vector3d x = truth.point_world_m(m, t.point);
      if (t.level == 0)
        x += draw_vector3(u, rng);  // the conflict
      else
        pos_strong.push_back(x);
      pos_both.push_back(x);
    }
    SolverOptions o = options_for(SegmentFit::rigid, RootMode::free);
    o.tolerance_m = 1e-7;
    o.stall_tolerance_m = 1e-8;
    o.max_iterations = 500;
    FabrikSolver alone(m, strong, o), prio(m, both, o);
    Posture p_alone = Posture::rest(m), p_both = Posture::rest(m);
    alone.solve(pos_strong, all_visible(strong.size()), p_alone);
    prio.solve(pos_both, all_visible(both.size()), p_both);
    double alone_sq = 0.0, both_sq = 0.0;
    for (std::size_t i = 0, k = 0; i < both.size(); ++i) {
      if (both[i].level != 1) continue;
      both_sq += std::pow(prio.target_distances_m()[i], 2);
      alone_sq += std::pow(alone.target_distances_m()[k++], 2);
    }
    worst_excess_m = std::max(worst_excess_m, std::sqrt(both_sq) - std::sqrt(alone_sq));
  }
  CAPTURE(worst_excess_m);
  INFO(
      "the strong level's error with a conflicting weak level, minus its error alone: stronger "
      "levels must take part in a weak level's pass with anchor_weight times their weight");
  // Measured: 4e-8 m with anchors, 1.4e-4 to 1.7e-4 m with them ignored or at weight 1.
  CHECK(worst_excess_m < 1e-5);
}

TEST_CASE("Warm start converges in fewer iterations than a cold start", "[fabrik][warm]") {
  const Model m = test::chain_model(8, 0.15);
  SolverOptions o = options_for(SegmentFit::paper);
  o.tolerance_m = 1e-4;
  FabrikSolver solver(m, {{m.find_point("j8"), 0, 1.0}}, o);
  Posture warm = Posture::rest(m);
  long warm_iters = 0, cold_iters = 0;  // reaching passes
  for (int k = 0; k < 100; ++k) {
    const double t = 0.02 * k;  // a target drifting slowly on a circle
    const std::vector<Eigen::Vector3d> target{{0.5 * std::cos(t), 0.8, 0.5 * std::sin(t)}};
    Posture cold = Posture::rest(m);
    const SolveResult rc = solver.solve(target, all_visible(1), cold);
    const SolveResult rw = solver.solve(target, all_visible(1), warm);
    REQUIRE(rc.status == SolveStatus::converged);
    REQUIRE(rw.status == SolveStatus::converged);
    cold_iters += rc.passes;
    warm_iters += rw.passes;
  }
  CAPTURE(warm_iters, cold_iters);
  CHECK(warm_iters * 3 < cold_iters * 2);  // at least a third fewer
}

TEST_CASE("A free root is placed by its own targets", "[fabrik][root]") {
  const Model m = test::fullbody_model();
  const std::vector<int> points = m.marker_points();
  std::vector<Target> targets;
  for (int p : points) targets.push_back({p, 0, 1.0});
  MotionSettings ms;
  ms.seed = 3;
  SyntheticMotion motion(m, ms);
  Posture truth = Posture::rest(m);
  motion.posture_at(0.7, truth);
  std::vector<Eigen::Vector3d> pos(points.size());
  motion.sample(truth, points, 0.0, pos);
  SolverOptions o = options_for(SegmentFit::rigid, RootMode::free);
  o.tolerance_m = 1e-5;
  FabrikSolver solver(m, targets, o);
  Posture posture = Posture::rest(m);
  const SolveResult r = solver.solve(pos, all_visible(pos.size()), posture);
  CAPTURE(r.iterations, r.rms_m, r.max_m, to_string(r.status));
  CHECK(r.rms_m < 1e-3);
  CHECK((posture.segments[0].base_world_m - truth.segments[0].base_world_m).norm() < 5e-3);
  CHECK(max_rigidity_error(m, posture) < kRigidRel);
}

// Two points leave a segment free to turn about the line through them: the fit must
// keep that turn where it was. A Newton step divided by the Hessian's rounding noise
// about that axis once turned the built-in model's pelvis by up to 7 degrees a pass
// when two of its four markers were hidden, and the revisits of the strongest level
// carried the whole body 150-600 mm off (scripts/dropout-probe).
TEST_CASE("A rotation fit that leaves an axis undetermined does not turn about it",
          "[fabrik][rotation]") {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal;
  double worst_rad = 0.0, worst_ratio = 0.0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Eigen::Quaterniond q =
        Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized();
    SegmentPose pose;
    pose.set_unit_rotation(q);
    const Eigen::Vector3d a_local(normal(rng), normal(rng), normal(rng));
    // Misaligned by theta (0 on every fourth trial) about an axis across the line.
    const double theta = trial % 4 == 0 ? 0.0 : std::pow(10.0, -1.0 - 8.0 * (trial % 97) / 96.0);
    const Eigen::Vector3d across = a_local.unitOrthogonal();
    const Eigen::Vector3d b_world = q * (Eigen::AngleAxisd(theta, across) * a_local);
    // The fit's m for drivers at +a and -a about their mean: both give b (R a)^T.
    const Eigen::Vector3d a_world = pose.r_world * a_local;
    const Eigen::Matrix3d m = 2.0 * b_world * a_world.transpose();
    fit_rotation_step(m, pose);
    const double turned_rad = pose.q_world.angularDistance(q);
    if (theta > 0.0)
      worst_ratio = std::max(worst_ratio, turned_rad / theta);
    else
      worst_rad = std::max(worst_rad, turned_rad);
  }
  CAPTURE(worst_rad, worst_ratio);
  CHECK(worst_rad < 1e-9);    // on target: no turn
  CHECK(worst_ratio < 1.01);  // off by theta: a turn by theta (about the axis across)
}

namespace {
// The built-in model solved as the embedded default solves it (pelvis markers one level
// stronger), each frame from the exact posture of the frame before, as a warm tracker starts,
// with two of `group`'s markers hidden (every pair in turn): the joint centres' largest
// distance from the truth.
double worst_with_pairs_hidden(const std::vector<std::string>& group, SolverOptions o) {
  const Model m = test::fullbody_model();
  const std::vector<int> points = m.marker_points();
  const std::vector<std::string> pelvis{"LASI", "LPSI", "RASI", "RPSI"};
  std::vector<Target> targets;
  std::vector<int> in_group;
  for (int p : points) {
    const std::string& name = m.points[p].name;
    const bool strong = std::find(pelvis.begin(), pelvis.end(), name) != pelvis.end();
    if (std::find(group.begin(), group.end(), name) != group.end())
      in_group.push_back(static_cast<int>(targets.size()));
    targets.push_back({p, strong ? 1 : 0, 1.0});
  }
  REQUIRE(in_group.size() == group.size());
  FabrikSolver solver(m, targets, o);
  SyntheticMotion motion(m, MotionSettings{});
  Posture before = Posture::rest(m), truth = Posture::rest(m);
  std::vector<Eigen::Vector3d> pos(points.size());
  double worst_m = 0.0;
  for (std::size_t a = 0; a < in_group.size(); ++a)
    for (std::size_t b = a + 1; b < in_group.size(); ++b)
      for (int f = 50; f < 1000; f += 50) {
        motion.posture_at((f - 1) / 100.0, before);
        motion.posture_at(f / 100.0, truth);
        motion.sample(truth, points, 0.0, pos);
        std::vector<std::uint8_t> visible = all_visible(pos.size());
        visible[in_group[a]] = visible[in_group[b]] = 0;
        Posture posture = before;
        solver.solve(pos, visible, posture);
        for (const Joint& j : m.joints)
          worst_m = std::max(
              worst_m,
              (posture.point_world_m(m, j.point) - truth.point_world_m(m, j.point)).norm());
      }
  return worst_m;
}

SolverOptions embedded_default_options() {
  SolverOptions o = options_for(SegmentFit::rigid, RootMode::free);
  o.tolerance_m = 1e-4;  // config/default.json's
  o.stall_tolerance_m = 1e-4;
  o.max_iterations = 50;
  return o;
}
}  // namespace

TEST_CASE(
    "The built-in model with two of its four strongest-level pelvis markers hidden "
    "stays on the truth",
    "[fabrik][priority][root]") {
  const double worst_m =
      worst_with_pairs_hidden({"LASI", "LPSI", "RASI", "RPSI"}, embedded_default_options());
  CAPTURE(worst_m);
  CHECK(worst_m < 5e-3);
}

// Without the carry, the loop reached 0.27 mm RMS and then left it, growing ~1.2x an
// iteration (the thigh turning about its long axis, the knee hinge following) to a cycle
// 0.1-0.2 m off (SolverOptions::fallback_carry).
TEST_CASE("The built-in model with two of a thigh's three markers hidden stays on the truth",
          "[fabrik][limits][carry]") {
  for (const auto& thigh : {std::vector<std::string>{"LTHI", "LTHF", "LKNE"},
                            std::vector<std::string>{"RTHI", "RTHF", "RKNE"}}) {
    const double worst_m = worst_with_pairs_hidden(thigh, embedded_default_options());
    CAPTURE(thigh[0], worst_m);
    CHECK(worst_m < 5e-3);
  }
}

TEST_CASE("Occluded targets are ignored and a frame with none is reported", "[fabrik]") {
  const Model m = test::paper_model();
  FabrikSolver solver(m, {{m.find_point("r_wrist"), 1, 1.0}, {m.find_point("l_wrist"), 0, 1.0}},
                      options_for(SegmentFit::paper));
  Posture posture = Posture::rest(m);
  const std::vector<Eigen::Vector3d> pos{{0.5, 0.5, 0.3}, {std::nan(""), 0, 0}};
  const SolveResult r = solver.solve(pos, std::vector<std::uint8_t>{1, 0}, posture);
  CHECK(r.visible_targets == 1);
  CHECK(r.status == SolveStatus::converged);
  CHECK(std::isnan(solver.target_distances_m()[1]));
  const Posture before = posture;
  const SolveResult none = solver.solve(pos, std::vector<std::uint8_t>{0, 0}, posture);
  CHECK(none.status == SolveStatus::no_targets);
  CHECK((posture.segments[3].base_world_m - before.segments[3].base_world_m).norm() == 0.0);
}

TEST_CASE("A solver reused across changing visibility and options matches a fresh one",
          "[fabrik]") {
  // solve() keeps the per-pass marks of the previous frame when visibility and
  // options are unchanged; every change must be seen.
  const Model m = test::paper_model();
  const std::vector<Target> targets{{m.find_point("r_wrist"), 1, 1.0},
                                    {m.find_point("l_wrist"), 0, 1.0}};
  const std::vector<Eigen::Vector3d> pos{{0.6, 0.7, 0.4}, {-0.7, 0.8, 0.5}};
  SolverOptions with_anchors = options_for(SegmentFit::rigid);
  SolverOptions flat = with_anchors;
  flat.use_priorities = false;
  SolverOptions literal = with_anchors;
  literal.anchor_weight = 0.0;
  const std::vector<std::vector<std::uint8_t>> frames{{1, 1}, {1, 1}, {1, 0}, {0, 1}, {1, 1}};
  FabrikSolver reused(m, targets, with_anchors);
  for (const SolverOptions& o : {with_anchors, flat, literal, with_anchors}) {
    reused.set_options(o);
    for (const auto& visible : frames) {
      FabrikSolver fresh(m, targets, o);
      Posture a = Posture::rest(m), b = Posture::rest(m);
      const SolveResult ra = reused.solve(pos, visible, a);
      const SolveResult rb = fresh.solve(pos, visible, b);
      CHECK(ra.iterations == rb.iterations);
      CHECK(ra.passes == rb.passes);
      for (std::size_t s = 0; s < a.segments.size(); ++s)
        CHECK((a.segments[s].base_world_m - b.segments[s].base_world_m).norm() == 0.0);
    }
  }
}

TEST_CASE("Jacobian baselines reach a reachable target and keep segments rigid", "[jacobian]") {
  const Model m = test::chain_model(4, 0.25);
  for (JacobianMethod method : {JacobianMethod::transpose, JacobianMethod::damped_least_squares}) {
    SolverOptions o = options_for(SegmentFit::paper);
    o.tolerance_m = 1e-3;
    o.max_iterations = 20000;
    JacobianSolver solver(m, {{m.find_point("j4"), 0, 1.0}}, o, {method, 0.01, 0.2});
    Posture posture = Posture::rest(m);
    const SolveResult r =
        solver.solve(std::vector<Eigen::Vector3d>{{0.4, 0.5, 0.3}}, all_visible(1), posture);
    CAPTURE(static_cast<int>(method), r.iterations, r.max_m);
    CHECK(r.status == SolveStatus::converged);
    CHECK(max_rigidity_error(m, posture) < kRigidRel);
    CHECK(max_joint_gap_m(m, posture) < 1e-12);
  }
}

TEST_CASE("Property: random trees keep geometry and the rigid fit never ends worse than it starts",
          "[fabrik][property]") {
  std::mt19937_64 rng(20261121);
  for (int trial = 0; trial < 120; ++trial) {
    const Model m = test::random_tree_model(rng, 2 + trial % 12);
    // Targets on a random subset of points, at positions of a random posture
    // (so they are reachable together), with random levels and weights.
    std::uniform_int_distribution<int> coin(0, 2), level(0, 2);
    std::uniform_real_distribution<double> weight(0.5, 2.0), angle(-1.2, 1.2);
    std::vector<Target> targets;
    for (int p = 0; p < static_cast<int>(m.points.size()); ++p)
      if (m.points[p].kind != PointKind::base && coin(rng) == 0)
        targets.push_back({p, level(rng), weight(rng)});
    if (targets.empty()) targets.push_back({static_cast<int>(m.points.size()) - 1, 0, 1.0});
    int strongest = 0;
    for (const Target& t : targets) strongest = std::max(strongest, t.level);
    std::vector<Eigen::Quaterniond> q_local(m.segments.size());
    for (auto& q : q_local)
      q = Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitZ());
    Posture goal = Posture::rest(m);
    set_from_local(m, Eigen::Vector3d(0.1, 0.2, 0.3), q_local, goal);
    std::vector<Eigen::Vector3d> pos;
    for (const Target& t : targets) pos.push_back(goal.point_world_m(m, t.point));
    const auto visible = all_visible(targets.size());
    // Sum of squared errors over all targets, or over the strongest level only.
    auto error_sq = [&](const Posture& p, bool strongest_only) {
      double sum = 0.0;
      for (std::size_t i = 0; i < targets.size(); ++i)
        if (!strongest_only || targets[i].level == strongest)
          sum += (p.point_world_m(m, targets[i].point) - pos[i]).squaredNorm();
      return sum;
    };

    for (SegmentFit fit : {SegmentFit::paper, SegmentFit::rigid})
      for (RootMode root : {RootMode::fixed, RootMode::free})
        for (bool prio : {false, true}) {
          SolverOptions o = options_for(fit, root);
          o.max_iterations = 100;
          o.tolerance_m = 1e-6;
          o.use_priorities = prio;
          FabrikSolver solver(m, targets, o);
          Posture posture = Posture::rest(m);
          if (root == RootMode::fixed)
            posture.segments[0].base_world_m = goal.segments[0].base_world_m;
          connect_joints(m, posture);
          const double start_sq = error_sq(posture, prio);
          const SolveResult r = solver.solve(pos, visible, posture);
          CAPTURE(trial, m.segments.size(), targets.size(), static_cast<int>(fit),
                  static_cast<int>(root), prio);
          REQUIRE(max_rigidity_error(m, posture) < kRigidRel);
          REQUIRE(max_joint_gap_m(m, posture) < 1e-9);
          REQUIRE(std::isfinite(r.rms_m));
          // The distances reported are those of the posture returned (links
          // are measured at their tips, before their one turn at the end).
          for (std::size_t i = 0; i < targets.size(); ++i)
            REQUIRE(std::abs(solver.target_distances_m()[i] -
                             (posture.point_world_m(m, targets[i].point) - pos[i]).norm()) < 1e-9);
          // The paper's rule aligns only the mean direction of a segment's
          // drivers, so with several targets on one segment it can end worse
          // than it started; the rigid fit never does (docs/solver.md: rigid fit).
          if (fit == SegmentFit::rigid) CHECK(error_sq(posture, prio) <= start_sq + 1e-9);
        }
  }
}

TEST_CASE("draw_vector3 and draw_rotation take their draws in x, y, z (w first) order", "[synth]") {
  int next = 0;
  auto counter = [&next](int&) { return static_cast<double>(++next); };
  int engine = 0;
  CHECK(draw_vector3(counter, engine).isApprox(Eigen::Vector3d(1, 2, 3)));
  const Eigen::Quaterniond q = draw_rotation(counter, engine);  // draws 4, 5, 6, 7
  const double n = std::sqrt(16.0 + 25.0 + 36.0 + 49.0);
  CHECK(q.w() == Approx(4.0 / n));
  CHECK(q.x() == Approx(5.0 / n));
  CHECK(q.z() == Approx(7.0 / n));
}
