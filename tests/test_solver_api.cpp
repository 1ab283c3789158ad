// The public solver API (solver.hpp): a plan shared read-only, a workspace per thread, and
// every misuse answered with a status value.
#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "solver/joint_angles.hpp"
#include "solver/model_builder.hpp"
#include "solver/solver.hpp"
#include "test_models.hpp"

using namespace fabrik;

namespace {

struct Problem {
  std::shared_ptr<const Model> model = std::make_shared<const Model>(test::fullbody_model());
  std::vector<Target> targets;
  std::vector<Eigen::Vector3d> target_world_m;
  std::vector<std::uint8_t> visible;
  Posture rest = Posture::rest(*model);

  explicit Problem(const Eigen::Vector3d& shift_m, bool limits = true) {
    if (!limits) {
      model = std::make_shared<const Model>(without_joint_limits(*model));
      rest = Posture::rest(*model);
    }
    for (int p : model->marker_points()) {
      targets.push_back({p, 0, 1.0});
      target_world_m.push_back(rest.point_world_m(*model, p) + shift_m);
    }
    visible.assign(targets.size(), 1);
  }
};

SolverOptions free_root() {
  SolverOptions o;
  o.root = RootMode::free;
  o.segment_fit = SegmentFit::rigid;
  o.tolerance_m = 1e-5;
  o.max_iterations = 200;
  return o;
}

}  // namespace

TEST_CASE("A plan solved in two workspaces on two threads gives the same posture", "[api]") {
  Problem pr(Eigen::Vector3d::Zero(), false);
  // Targets where a bent body has its markers: the solve from rest has to bend every joint.
  std::vector<Eigen::Quaterniond> q_local(pr.model->segments.size());
  for (std::size_t s = 0; s < q_local.size(); ++s)
    q_local[s] = Eigen::AngleAxisd(0.25, Eigen::Vector3d(1.0, 0.5 * static_cast<double>(s), 0.3).normalized());
  Posture bent = pr.rest;
  set_from_local(*pr.model, Eigen::Vector3d(0.1, 0.9, -0.2), q_local, bent);
  for (std::size_t i = 0; i < pr.targets.size(); ++i)
    pr.target_world_m[i] = bent.point_world_m(*pr.model, pr.targets[i].point);
  const SolverPlan plan(pr.model, pr.targets, free_root());
  Posture postures[2] = {pr.rest, pr.rest};
  SolveResult results[2];
  std::vector<std::thread> threads;
  for (int k = 0; k < 2; ++k)
    threads.emplace_back([&, k] {
      SolverWorkspace w(plan);
      results[k] = solve(plan, w, pr.target_world_m, pr.visible, postures[k]);
    });
  for (auto& t : threads) t.join();
  CHECK(results[0].status == SolveStatus::converged);
  CHECK(results[0].iterations > 1);
  CHECK(results[0].status == results[1].status);
  CHECK(results[0].iterations == results[1].iterations);
  for (std::size_t s = 0; s < postures[0].segments.size(); ++s) {
    CHECK(postures[0].segments[s].base_world_m == postures[1].segments[s].base_world_m);
    CHECK(postures[0].segments[s].q_world.coeffs() == postures[1].segments[s].q_world.coeffs());
  }
}

TEST_CASE("A workspace made for another plan is refused and the posture kept", "[api]") {
  const Problem pr(Eigen::Vector3d(0.03, 0, 0));
  const SolverPlan plan(pr.model, pr.targets, free_root());
  const SolverPlan same_problem(pr.model, pr.targets, free_root());
  SolverWorkspace foreign(same_problem);
  Posture p = pr.rest;
  const SolveResult r = solve(plan, foreign, pr.target_world_m, pr.visible, p);
  CHECK(r.status == SolveStatus::wrong_workspace);
  CHECK(to_string(r.status) == "wrong_workspace");
  CHECK(p.segments[0].base_world_m == pr.rest.segments[0].base_world_m);
  // A copy of a plan is the same problem: its workspaces fit both.
  const SolverPlan copy = plan;
  SolverWorkspace w(copy);
  CHECK(w.plan_id() == plan.id());
  CHECK(solve(plan, w, pr.target_world_m, pr.visible, p).status == SolveStatus::converged);
  // A moved-from workspace holds nothing and is refused too.
  SolverWorkspace moved(std::move(w));
  CHECK(solve(plan, w, pr.target_world_m, pr.visible, p).status == SolveStatus::wrong_workspace);
  CHECK(solve(plan, moved, pr.target_world_m, pr.visible, p).status != SolveStatus::wrong_workspace);
}

TEST_CASE("Inputs of the wrong size are a status, not a crash", "[api]") {
  const Problem pr(Eigen::Vector3d(0.01, 0, 0));
  const SolverPlan plan(pr.model, pr.targets, free_root());
  SolverWorkspace w(plan);
  Posture p = pr.rest;
  const std::span<const Eigen::Vector3d> short_targets(pr.target_world_m.data(),
                                                       pr.target_world_m.size() - 1);
  CHECK(solve(plan, w, short_targets, pr.visible, p).status == SolveStatus::size_mismatch);
  Posture wrong_model;  // no segments
  CHECK(solve(plan, w, pr.target_world_m, pr.visible, wrong_model).status ==
        SolveStatus::size_mismatch);
  CHECK(p.segments[0].base_world_m == pr.rest.segments[0].base_world_m);
}

TEST_CASE("A plan with a target outside the model is refused at setup", "[api]") {
  const Problem pr(Eigen::Vector3d::Zero());
  std::vector<Target> bad = pr.targets;
  bad.push_back({static_cast<int>(pr.model->points.size()), 0, 1.0});
  CHECK_THROWS_AS(SolverPlan(pr.model, bad, free_root()), std::invalid_argument);
  CHECK_THROWS_AS(SolverPlan(nullptr, pr.targets, free_root()), std::invalid_argument);
}

TEST_CASE("A target, rotation or start that is not finite is a status, the posture kept", "[api]") {
  const Problem pr(Eigen::Vector3d(0.01, 0, 0));
  const SolverPlan plan(pr.model, pr.targets, free_root());
  SolverWorkspace w(plan);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const double bad : {nan, std::numeric_limits<double>::infinity()}) {
    CAPTURE(bad);
    std::vector<Eigen::Vector3d> targets = pr.target_world_m;
    targets[5].x() = bad;
    Posture p = pr.rest;
    const SolveResult r = solve(plan, w, targets, pr.visible, p);
    CHECK(r.status == SolveStatus::non_finite_input);
    CHECK(to_string(r.status) == "non_finite_input");
    CHECK(p.segments[0].base_world_m == pr.rest.segments[0].base_world_m);
    // The same target not visible is not looked at: the solve goes on.
    std::vector<std::uint8_t> visible = pr.visible;
    visible[5] = 0;
    CHECK(solve(plan, w, targets, visible, p).status == SolveStatus::converged);
    for (const SegmentPose& s : p.segments) CHECK(s.base_world_m.allFinite());
    // A start posture that is not finite (one spoilt by an earlier solve) is refused too.
    Posture spoilt = pr.rest;
    spoilt.segments[2].base_world_m.y() = bad;
    CHECK(solve(plan, w, pr.target_world_m, pr.visible, spoilt).status ==
          SolveStatus::non_finite_input);
  }
  // An orientation target: a rotation of zero length is no rotation.
  const SolverPlan turned(pr.model, pr.targets, free_root(), {{1, 0, 1.0}});
  SolverWorkspace wt(turned);
  Posture p = pr.rest;
  const std::vector<Eigen::Quaterniond> zero{Eigen::Quaterniond(0, 0, 0, 0)};
  const std::vector<std::uint8_t> seen{1}, unseen{0};
  CHECK(solve(turned, wt, pr.target_world_m, pr.visible, zero, seen, p).status ==
        SolveStatus::non_finite_input);
  CHECK(solve(turned, wt, pr.target_world_m, pr.visible, zero, unseen, p).status ==
        SolveStatus::converged);
}

TEST_CASE("Options that cannot run a solve are refused at setup, with the option's name", "[api]") {
  const Problem pr(Eigen::Vector3d::Zero());
  auto refused = [&](auto&& change) {
    SolverOptions o = free_root();
    change(o);
    try {
      SolverPlan plan(pr.model, pr.targets, o);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  CHECK_THAT(refused([&](SolverOptions& o) { o.tolerance_m = nan; }),
             Catch::Contains("tolerance_m must be a finite number"));
  CHECK_THAT(refused([](SolverOptions& o) { o.stall_tolerance_m = -1e-6; }),
             Catch::Contains("stall_tolerance_m"));
  CHECK_THAT(refused([](SolverOptions& o) { o.max_iterations = -1; }),
             Catch::Contains("max_iterations must be at least 1"));
  CHECK_THAT(refused([](SolverOptions& o) { o.level_passes = 0; }),
             Catch::Contains("level_passes must be at least 1"));
  CHECK_THAT(refused([](SolverOptions& o) { o.orientation_lever_m = 0.0; }),
             Catch::Contains("orientation_lever_m must be positive"));
  CHECK_THAT(refused([](SolverOptions& o) { o.subtree_carry = INFINITY; }),
             Catch::Contains("subtree_carry"));
  CHECK(refused([](SolverOptions& o) { o.anchor_weight = 0.0; }) == "accepted");
  CHECK(refused([](SolverOptions&) {}) == "accepted");
}

TEST_CASE("Kinematics and coordinates refuse spans of the wrong size, writing nothing", "[api]") {
  const Problem pr(Eigen::Vector3d::Zero());
  const Model& m = *pr.model;
  std::vector<double> values(m.coordinates.size() + 1, -7.0);
  CHECK_FALSE(coordinate_values(m, pr.rest, std::span(values).first(1)));
  CHECK(values[1] == -7.0);  // was written past the span's end
  CHECK_FALSE(coordinate_values(m, pr.rest, values));
  CHECK(coordinate_values(m, pr.rest, std::span(values).first(m.coordinates.size())));
  const std::vector<double> previous(m.coordinates.size(), 0.0);
  CHECK_FALSE(unwrap_coordinates(m, {}, std::span(values).first(m.coordinates.size())));
  CHECK_FALSE(unwrap_coordinates(m, previous, values));
  CHECK(unwrap_coordinates(m, previous, std::span(values).first(m.coordinates.size())));
  Posture p = pr.rest;
  const std::vector<Eigen::Quaterniond> q_local(m.segments.size(), Eigen::Quaterniond::Identity());
  const Eigen::Vector3d moved(1, 2, 3);
  CHECK_FALSE(set_from_local(m, moved, std::span(q_local).first(1), p));
  CHECK(p.segments[0].base_world_m == pr.rest.segments[0].base_world_m);
  Posture empty;
  CHECK_FALSE(set_from_local(m, moved, q_local, empty));
  CHECK_FALSE(connect_joints(m, empty));
  CHECK(set_from_local(m, moved, q_local, p));
  CHECK(p.segments[0].base_world_m == moved);
}

TEST_CASE("Angles of a segment index outside the model are NaN, the posture untouched", "[api]") {
  const Problem pr(Eigen::Vector3d::Zero());
  const Model& m = *pr.model;
  const int n = static_cast<int>(m.segments.size());
  const int last = n - 1;
  // Known answers inside: at rest every segment's frame is the world's, so a joint's rotation
  // is its anatomical frame relative to its parent's.
  const int parent = m.segments[last].parent;
  REQUIRE(parent >= 0);
  const Eigen::Matrix3d a_parent = m.segments[parent].q_anatomical.toRotationMatrix();
  const Eigen::Matrix3d a_child = m.segments[last].q_anatomical.toRotationMatrix();
  CHECK(anatomical_world(m, pr.rest, last).isApprox(a_child));
  CHECK(joint_angles_rad(m, pr.rest, last).isApprox(cardan_zxy(a_parent.transpose() * a_child)));
  for (int s : {-1, n, n + 1000}) {
    INFO("segment " << s);
    CHECK(joint_angles_rad(m, pr.rest, s).array().isNaN().all());
    CHECK(anatomical_world(m, pr.rest, s).array().isNaN().all());
    CHECK(relative_anatomical(m, pr.rest, last, s == -1 ? -2 : s).array().isNaN().all());
    Posture p = pr.rest;
    CHECK_FALSE(enforce_joint_limits(m, s, Eigen::Quaterniond::Identity(), p));
  }
  CHECK(relative_anatomical(m, pr.rest, last, -1).isApprox(anatomical_world(m, pr.rest, last)));
  // A posture of another model (fewer poses) is refused for every index.
  Posture short_posture = pr.rest;
  short_posture.segments.pop_back();
  CHECK(joint_angles_rad(m, short_posture, 0).array().isNaN().all());
  // A limited joint turned far out of its range: turned back in a posture of the model's
  // size, refused (untouched) in one of another size.
  int limited = -1;
  for (int s = 0; s < last && limited < 0; ++s)
    if (m.segments[s].parent >= 0 && m.segments[s].joint.limited()) limited = s;
  REQUIRE(limited >= 0);
  const Eigen::Quaterniond turned(Eigen::AngleAxisd(3.0, Eigen::Vector3d(1, 1, 0).normalized()));
  Posture p = pr.rest;
  p.segments[limited].set_unit_rotation(turned);
  short_posture.segments[limited].set_unit_rotation(turned);
  CHECK(enforce_joint_limits(m, limited, Eigen::Quaterniond::Identity(), p));
  CHECK_FALSE(enforce_joint_limits(m, limited, Eigen::Quaterniond::Identity(), short_posture));
  CHECK(short_posture.segments[limited].q_world.isApprox(turned));
}
