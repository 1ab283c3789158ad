// `fabrik bench convergence`: how often, and in how many iterations, the solver meets its
// tolerance on trees and chains whose targets can be met exactly (synth/reach_problems.hpp):
// stars of 10, 20 and 50 end effectors, chains of 100 and 200 segments, cold (from rest)
// and warm (from the previous solve, the targets moved on a little).
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fabrik::bench {

struct ConvergenceOptions {
  int solves = 500;  // per case and start (cold, warm)
  unsigned seed = 1;
  // The stall tolerance as a fraction of the tolerance (the figures: tol / 100).
  double stall_ratio = 0.01;
  int max_iterations = 0;          // 0: SolverOptions' default
  // Each joint of a target posture turned from rest by up to this; 0: the case's own (0.1 rad
  // for stars, 0.4 for chains: with the stall stop off, FABRIK then meets most warm solves
  // within the default budget; straighter chains converge far slower).
  double max_turn_rad = 0.0;
  std::vector<std::string> cases;  // "star50", "chain200_10um", ...; empty: all
};
nlohmann::json run_convergence(const ConvergenceOptions& options);
std::string convergence_table(const nlohmann::json& result);

}  // namespace fabrik::bench
