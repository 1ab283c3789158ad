#include "convergence_bench.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <stdexcept>

#include "solver/fabrik_solver.hpp"
#include "stats.hpp"
#include "synth/reach_problems.hpp"

namespace fabrik::bench {

using nlohmann::json;

namespace {

struct Case {
  std::string name;
  ReachProblem problem;
  double tolerance_m;
  // A warm frame's turn of each joint, at most: the targets move by millimetres a frame (the
  // bench reports how far), about what 100 Hz motion capture sees.
  double warm_step_rad;
  double max_turn_rad;  // of a target posture's joints from rest
};

std::vector<Case> all_cases() {
  std::vector<Case> cases;
  for (int arms : {10, 20, 50}) cases.push_back({"", star_problem(arms), 1e-3, 0.01, 0.1});
  for (int segments : {100, 200}) {
    cases.push_back({"", chain_problem(segments), 1e-3, 0.002, 0.4});
    cases.push_back({"", chain_problem(segments), 1e-5, 0.002, 0.4});
  }
  for (Case& c : cases)
    c.name = c.problem.name + (c.tolerance_m < 1e-3 ? "_10um" : "");
  return cases;
}

// Solves of one case from one kind of start, with their figures.
json run_case(const Case& c, bool warm, const ConvergenceOptions& options) {
  const Model& m = *c.problem.model;
  SolverOptions o;
  o.tolerance_m = c.tolerance_m;
  o.stall_tolerance_m = c.tolerance_m * options.stall_ratio;
  if (options.max_iterations > 0) o.max_iterations = options.max_iterations;
  FabrikSolver solver(c.problem.model, c.problem.targets, o);
  const double max_turn_rad = options.max_turn_rad > 0.0 ? options.max_turn_rad : c.max_turn_rad;
  ReachPoses poses(c.problem, options.seed, max_turn_rad);
  const std::size_t n = c.problem.targets.size();
  std::vector<Eigen::Vector3d> target_m(n);
  const std::vector<std::uint8_t> visible(n, 1);
  const Posture rest = Posture::rest(m);
  Posture posture = rest;
  if (warm) {  // the first frame, from rest, is not counted: warm solves follow it
    poses.draw(target_m);
    solver.solve(target_m, visible, posture);
  }
  std::vector<double> iterations, times_us, target_steps_m;
  std::vector<Eigen::Vector3d> last_target_m(n);
  double worst_m = 0.0, total_s = 0.0, total_iterations = 0.0;
  int within = 0, stalled = 0, out_of_iterations = 0;
  for (int i = 0; i < options.solves; ++i) {
    if (warm) {
      last_target_m = target_m;
      poses.step(target_m, c.warm_step_rad);
      double step_m = 0.0;
      for (std::size_t k = 0; k < n; ++k)
        step_m = std::max(step_m, (target_m[k] - last_target_m[k]).norm());
      target_steps_m.push_back(step_m);
    } else {
      poses.draw(target_m);
      posture = rest;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const SolveResult r = solver.solve(target_m, visible, posture);
    const auto t1 = std::chrono::steady_clock::now();
    const double s = std::chrono::duration<double>(t1 - t0).count();
    total_s += s;
    times_us.push_back(s * 1e6);
    iterations.push_back(r.iterations);
    total_iterations += r.iterations;
    worst_m = std::max(worst_m, r.max_m);
    within += r.max_m <= c.tolerance_m ? 1 : 0;
    stalled += r.status == SolveStatus::stalled ? 1 : 0;
    out_of_iterations += r.status == SolveStatus::max_iterations ? 1 : 0;
  }
  const double segments = static_cast<double>(m.segments.size());
  return {{"case", c.name},
          {"start", warm ? "warm" : "cold"},
          {"segments", m.segments.size()},
          {"end_effectors", n},
          {"tolerance_um", c.tolerance_m * 1e6},
          {"max_turn_rad", max_turn_rad},
          {"stall_tolerance_um", o.stall_tolerance_m * 1e6},
          {"max_iterations", o.max_iterations},
          {"solves", options.solves},
          // Warm: how far the farthest-moving target moved per frame, on average.
          {"target_step_mm_mean", warm ? mean(target_steps_m) * 1e3 : 0.0},
          {"within_tolerance_pct", 100.0 * within / std::max(1, options.solves)},
          {"stalled", stalled},
          {"out_of_iterations", out_of_iterations},
          {"iterations_mean", mean(iterations)},
          {"iterations_p95", quantile(iterations, 0.95)},
          {"iterations_max", quantile(iterations, 1.0)},
          {"worst_um", worst_m * 1e6},
          {"us_per_solve_mean", mean(times_us)},
          {"us_per_solve_p50", quantile(times_us, 0.5)},
          {"ns_per_segment_iteration",
           total_iterations > 0 ? total_s * 1e9 / (total_iterations * segments) : 0.0}};
}

}  // namespace

json run_convergence(const ConvergenceOptions& options) {
  if (options.solves < 1) throw std::invalid_argument("--solves must be at least 1");
  std::vector<Case> cases = all_cases();
  for (const std::string& name : options.cases)
    if (std::none_of(cases.begin(), cases.end(), [&](const Case& c) { return c.name == name; }))
      throw std::invalid_argument("no convergence case '" + name + "'");
  json out;
  out["benchmark"] = "convergence";
  out["solves"] = options.solves;
  out["seed"] = options.seed;
  out["stall_ratio"] = options.stall_ratio;
  out["runs"] = json::array();
  for (const Case& c : cases) {
    if (!options.cases.empty() &&
        std::find(options.cases.begin(), options.cases.end(), c.name) == options.cases.end())
      continue;
    for (bool warm : {false, true}) out["runs"].push_back(run_case(c, warm, options));
  }
  return out;
}

std::string convergence_table(const json& r) {
  char line[256];
  std::snprintf(line, sizeof line,
                "Convergence on reachable targets: %d solves per row, seed %u, stall tolerance = "
                "tolerance x %g\n\n",
                r["solves"].get<int>(), r["seed"].get<unsigned>(), r["stall_ratio"].get<double>());
  std::string s = line;
  s += "case           start  segs  tol_um  step_mm  within_%  stalled  max_it  iter_mean  p95  "
       "max  worst_um   us_mean  ns/seg/it\n";
  for (const json& run : r["runs"]) {
    std::snprintf(line, sizeof line,
                  "%-14s %-5s %5d %7.0f %8.1f %9.1f %8d %7d %10.1f %4.0f %4.0f %9.2f %9.1f "
                  "%10.1f\n",
                  run["case"].get<std::string>().c_str(), run["start"].get<std::string>().c_str(),
                  run["segments"].get<int>(), run["tolerance_um"].get<double>(),
                  run["target_step_mm_mean"].get<double>(),
                  run["within_tolerance_pct"].get<double>(), run["stalled"].get<int>(),
                  run["out_of_iterations"].get<int>(), run["iterations_mean"].get<double>(),
                  run["iterations_p95"].get<double>(), run["iterations_max"].get<double>(),
                  run["worst_um"].get<double>(), run["us_per_solve_mean"].get<double>(),
                  run["ns_per_segment_iteration"].get<double>());
    s += line;
  }
  s += "\n(step_mm: warm, how far the farthest-moving target moved per frame, mean; within_%:\n"
       " solves ending with every target within tolerance; stalled, max_it: solves stopped by\n"
       " the stall rule or the iteration budget; ns/seg/it: solve time over iterations x\n"
       " segments)\n";
  return s;
}

}  // namespace fabrik::bench
