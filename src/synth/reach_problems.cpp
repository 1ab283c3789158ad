#include "reach_problems.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "random_draws.hpp"
#include "solver/model_builder.hpp"

namespace fabrik {

namespace {

// Unit directions spread evenly over the sphere (a Fibonacci lattice).
Eigen::Vector3d spread_direction(int k, int n) {
  const double y = 1.0 - 2.0 * (k + 0.5) / n;
  const double r = std::sqrt(std::max(0.0, 1.0 - y * y));
  const double phi = k * std::numbers::pi * (3.0 - std::sqrt(5.0));
  return {r * std::cos(phi), y, r * std::sin(phi)};
}

SegmentSpec segment(const std::string& name, const std::string& parent, const std::string& base,
                    const std::string& tip, const Eigen::Vector3d& p_tip_m) {
  SegmentSpec s;
  s.name = name;
  s.parent = parent;
  s.base = base;
  s.points.push_back({tip, p_tip_m, false});
  return s;
}

ReachProblem problem(std::string name, const std::vector<SegmentSpec>& specs,
                     const std::vector<std::string>& effectors) {
  ReachProblem p;
  auto model = std::make_shared<const Model>(build_model(name, specs, Eigen::Vector3d::Zero()));
  for (const std::string& e : effectors) p.targets.push_back({model->find_point(e), 0, 1.0});
  p.model = std::move(model);
  p.name = std::move(name);
  return p;
}

}  // namespace

ReachProblem star_problem(int arms) {
  constexpr int kArmSegments = 3;
  std::vector<SegmentSpec> specs;
  specs.push_back(segment("trunk0", "", "root", "t1", {0.0, 0.2, 0.0}));
  // The trunk's tip holds one joint point per arm, all at the same place.
  SegmentSpec trunk1 = segment("trunk1", "trunk0", "t1", "hub0", {0.0, 0.2, 0.0});
  for (int a = 1; a < arms; ++a)
    trunk1.points.push_back({"hub" + std::to_string(a), {0.0, 0.2, 0.0}, false});
  specs.push_back(trunk1);
  std::vector<std::string> effectors;
  for (int a = 0; a < arms; ++a) {
    const Eigen::Vector3d bone_m = 0.1 * spread_direction(a, arms);
    std::string base = "hub" + std::to_string(a), parent = "trunk1";
    for (int k = 0; k < kArmSegments; ++k) {
      const std::string name = "a" + std::to_string(a) + "_" + std::to_string(k);
      const std::string tip = name + "_tip";
      specs.push_back(segment(name, parent, base, tip, bone_m));
      parent = name;
      base = tip;
    }
    effectors.push_back(base);
  }
  return problem("star" + std::to_string(arms), specs, effectors);
}

ReachProblem chain_problem(int segments) {
  std::vector<SegmentSpec> specs;
  const Eigen::Vector3d bone_m(0.0, 1.0 / segments, 0.0);
  for (int i = 0; i < segments; ++i)
    specs.push_back(segment("s" + std::to_string(i), i == 0 ? "" : "s" + std::to_string(i - 1),
                            "j" + std::to_string(i), "j" + std::to_string(i + 1), bone_m));
  return problem("chain" + std::to_string(segments), specs, {"j" + std::to_string(segments)});
}

ReachPoses::ReachPoses(const ReachProblem& problem, unsigned seed, double max_turn_rad)
    : model_(problem.model),
      max_turn_rad_(max_turn_rad),
      rng_(seed),
      q_local_(problem.model->segments.size(), Eigen::Quaterniond::Identity()),
      turn_axis_(problem.model->segments.size(), Eigen::Vector3d::Zero()),
      posture_(Posture::rest(*problem.model)) {
  for (const Target& t : problem.targets) points_.push_back(t.point);
}

void ReachPoses::draw(std::span<Eigen::Vector3d> target_world_m) {
  std::normal_distribution<double> gaussian;
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (std::size_t s = 0; s < q_local_.size(); ++s) {
    const Eigen::Vector3d axis = draw_vector3(gaussian, rng_).normalized();
    const double angle_rad = max_turn_rad_ * unit(rng_);
    q_local_[s] = Eigen::Quaterniond(Eigen::AngleAxisd(angle_rad, axis));
    const Eigen::Vector3d turn_axis = draw_vector3(gaussian, rng_).normalized();
    turn_axis_[s] = unit(rng_) * turn_axis;
  }
  targets(target_world_m);
}

void ReachPoses::step(std::span<Eigen::Vector3d> target_world_m, double step_rad) {
  for (std::size_t s = 0; s < q_local_.size(); ++s) {
    const double angle_rad = step_rad * turn_axis_[s].norm();
    if (angle_rad > 0.0)
      q_local_[s] =
          (q_local_[s] * Eigen::AngleAxisd(angle_rad, turn_axis_[s].normalized())).normalized();
  }
  targets(target_world_m);
}

void ReachPoses::targets(std::span<Eigen::Vector3d> target_world_m) {
  const Model& m = *model_;
  set_from_local(m, m.root_rest_m, q_local_, posture_);
  for (std::size_t i = 0; i < points_.size(); ++i)
    target_world_m[i] = posture_.point_world_m(m, points_[i]);
}

}  // namespace fabrik
