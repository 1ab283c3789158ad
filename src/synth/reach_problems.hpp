// Reach problems with an exact solution, for the convergence bench and its tests: a star
// (a trunk, then arms from its tip, one end effector per arm) or a single chain (one at its
// tip), with target positions taken from postures of random joint turns of the same model,
// so every target set can be met exactly. Solver types only: no I/O.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "solver/model.hpp"
#include "solver/posture.hpp"
#include "solver/solve_types.hpp"

namespace fabrik {

struct ReachProblem {
  std::string name;  // "star50", "chain200"
  std::shared_ptr<const Model> model;
  std::vector<Target> targets;  // one per end effector, all at level 0
};

// Two trunk segments of 0.2 m from the pinned root, then `arms` arms of three 0.1 m
// segments, all based at the trunk's tip (a sub-base every arm pulls on), pointing at rest
// along directions spread over the sphere. 2 + 3 * arms segments.
ReachProblem star_problem(int arms);
// `segments` straight segments of 1 m / segments each (1 m in all), the tip the target.
ReachProblem chain_problem(int segments);

// Postures of a problem's model from random joint turns, and the targets they give.
class ReachPoses {
 public:
  // Each joint (and the root) turns about a random axis by up to max_turn_rad.
  ReachPoses(const ReachProblem& problem, unsigned seed, double max_turn_rad = 0.4);
  // A new, independent posture (a cold solve's targets).
  void draw(std::span<Eigen::Vector3d> target_world_m);
  // The current posture moved on by one frame (a warm solve's targets): every joint keeps
  // turning at its own rate, about its own axis, by up to step_rad a frame (drawn once per
  // draw()).
  void step(std::span<Eigen::Vector3d> target_world_m, double step_rad = 0.01);
  const Posture& posture() const { return posture_; }

 private:
  void targets(std::span<Eigen::Vector3d> target_world_m);
  std::shared_ptr<const Model> model_;
  std::vector<int> points_;  // the targets' points
  double max_turn_rad_;
  std::mt19937_64 rng_;
  std::vector<Eigen::Quaterniond> q_local_;
  std::vector<Eigen::Vector3d> turn_axis_;  // per joint: the warm motion's axis, times 0..1
  Posture posture_;
};

}  // namespace fabrik
