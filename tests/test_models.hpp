// Models and checks shared by the solver tests.
#pragma once

#include <memory>
#include <random>
#include <string>
#include <vector>

#include "solver/model.hpp"
#include "solver/model_builder.hpp"
#include "solver/posture.hpp"
#include "solver/solve_types.hpp"

namespace fabrik::test {

// A straight-ish chain of n segments of the given length along +Y, slightly
// bent so FABRIK has a plane to bend in.
Model chain_model(int n, double length_m);
// The paper's upper body, loaded from config/models/paper_upper_body.json.
Model paper_model();
// The built-in full-body model (config/models/fullbody.json).
Model fullbody_model();
// A random tree: up to `n_segments` segments, each with 1-4 points, some of
// them markers; all lengths in [0.05, 0.5] m.
Model random_tree_model(std::mt19937_64& rng, int n_segments);
// The specs behind random_tree_model (to add frames and joints to).
std::vector<SegmentSpec> random_tree_specs(std::mt19937_64& rng, int n_segments);

// Largest relative change of any point-to-point distance within a segment
// between the rest posture and `posture`.
double max_rigidity_error(const Model& model, const Posture& posture);
// Largest distance between a joint as placed by the parent and the child's base.
double max_joint_gap_m(const Model& model, const Posture& posture);
// Largest amount by which any limited joint lies outside its ranges (radians).
double max_limit_excess_rad(const Model& m, const Posture& p);
// Largest distance of a hinge child's point from the plane it must stay in.
double max_hinge_plane_m(const Model& m, const Posture& p);

// An upper arm whose only marker lies on its long axis and a forearm on a hinge with two
// wrist markers; the goal turns the upper arm 60 deg about its axis and flexes the elbow
// further: reachable exactly, but only if the forearm's markers turn the upper arm, which its
// joint point cannot (the subtree carry), and then slowly, as coordinate descent goes along a
// valley. One target per marker, at the goal; the start has the elbow half flexed.
struct HingedArm {
  std::shared_ptr<const Model> model;
  std::vector<Target> targets;
  std::vector<Eigen::Vector3d> goal_m;
  Posture start;
};
HingedArm hinged_arm();

}  // namespace fabrik::test
