// `fabrik bench paper`: Moya & Colloud (2013), Figure 2, reproduced in 3D.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>

#include "bench.hpp"
#include "config/config_error.hpp"
#include "paper_checks.hpp"
#include "paper_experiment.hpp"
#include "solver/fabrik_solver.hpp"
#include "solver/jacobian_solver.hpp"
#include "stats.hpp"

namespace fabrik::bench {

using nlohmann::json;

namespace {

// Every algorithm of the experiment on one model, from the same start.
struct Runs {
  Run flat, prio, flat_paper, prio_paper, jt, jt_equal;
};

Runs run_all(const Experiment& e, const std::shared_ptr<const Model>& model, int repeats,
             int jt_repeats, bool paper_rule) {
  Runs r;
  SolverOptions flat = e.solver;
  flat.use_priorities = false;
  FabrikSolver fabrik(model, e.targets, flat);
  r.flat = time_solver(fabrik, *model, e, repeats);

  SolverOptions prio = e.solver;
  prio.use_priorities = true;
  FabrikSolver prioritized(model, e.targets, prio);
  r.prio = time_solver(prioritized, *model, e, repeats);

  if (paper_rule) {  // the same two runs with the paper's literal subbase rule, for comparison
    SolverOptions flat_paper = flat, prio_paper = prio;
    flat_paper.segment_fit = prio_paper.segment_fit = SegmentFit::paper;
    FabrikSolver fabrik_paper(model, e.targets, flat_paper);
    r.flat_paper = time_solver(fabrik_paper, *model, e, repeats);
    FabrikSolver prioritized_paper(model, e.targets, prio_paper);
    r.prio_paper = time_solver(prioritized_paper, *model, e, repeats);
  }

  JacobianSolver jt(model, e.targets, flat, {JacobianMethod::transpose, 0.0, 0.2});
  r.jt = time_solver(jt, *model, e, jt_repeats);

  // The same JT, timed to the accuracy FABRIK ends with: it stops when both
  // wrists are at least as close as FABRIK's final errors (tolerance = the
  // worse of them; no stall rule). Its own stall rule above stops it short of
  // that (0.2 mm further from the optimum); the paper compares algorithms at
  // the same tolerance.
  SolverOptions equal = flat;
  equal.tolerance_m = std::max(r.flat.distances_m[0], r.flat.distances_m[1]);
  equal.stall_tolerance_m = 0.0;
  JacobianSolver jt_equal(model, e.targets, equal, {JacobianMethod::transpose, 0.0, 0.2});
  r.jt_equal = time_solver(jt_equal, *model, e, std::max(5, repeats / 10));
  return r;
}

json ratios_json(const Runs& r) {
  return {{"jt_over_fabrik", r.jt.median_us() / r.flat.median_us()},
          {"jt_over_prioritized", r.jt.median_us() / r.prio.median_us()},
          {"jt_to_fabrik_accuracy_over_fabrik", r.jt_equal.median_us() / r.flat.median_us()},
          {"jt_to_fabrik_accuracy_over_prioritized", r.jt_equal.median_us() / r.prio.median_us()},
          {"paper_jt_over_fabrik", 25.0},
          {"paper_jt_over_prioritized", 7.0}};
}

json algorithms_json(const Experiment& e, const Model& model, const Runs& r, bool paper_rule) {
  json a = {{"fabrik", run_json(e, model, r.flat)},
            {"fabrik_prioritized", run_json(e, model, r.prio)},
            {"jacobian_transpose", run_json(e, model, r.jt)},
            {"jacobian_transpose_to_fabrik_accuracy", run_json(e, model, r.jt_equal)}};
  if (paper_rule) {
    a["fabrik_paper_rule"] = run_json(e, model, r.flat_paper);
    a["fabrik_prioritized_paper_rule"] = run_json(e, model, r.prio_paper);
  }
  a["jacobian_transpose_to_fabrik_accuracy"]["note"] =
      "JT run until both wrist errors are no larger than FABRIK's final ones (tolerance = "
      "FABRIK's worse wrist error, no stall rule); jacobian_transpose uses the experiment's "
      "stopping rule and stops further from the optimum";
  return a;
}

// The same experiment with the limits model: every algorithm must end with
// every joint in range; FABRIK's errors are compared with the Jacobian's.
json limits_json(const Experiment& e, int repeats) {
  const Model& m = *e.limits_model;
  // Projected after every step, JT creeps along the limits and its own
  // stopping rule does not stop it before max_iterations: a few runs suffice.
  const Runs r = run_all(e, e.limits_model, repeats, 5, false);
  json checks = json::object();
  const std::pair<const char*, const Run*> runs[] = {
      {"fabrik", &r.flat}, {"fabrik_prioritized", &r.prio}, {"jacobian_transpose", &r.jt},
      {"jacobian_transpose_to_fabrik_accuracy", &r.jt_equal}};
  for (const auto& [name, run] : runs) {
    const double excess = max_limit_excess_deg(m, run->posture);
    checks[std::string(name) + "_within_limits"] =
        check(excess <= 1e-6, excess, 1e-6, "deg", "largest angle of any joint beyond its range");
  }
  checks["priorities_favour_strong"] =
      check(r.prio.distances_m[0] < r.flat.distances_m[0],
            (r.flat.distances_m[0] - r.prio.distances_m[0]) * 1e3, 0.0, "mm",
            "the strong wrist gets closer with priorities than without");
  // The best the strong wrist can do within the limits: FABRIK on it alone.
  SolverOptions alone_options = e.solver;
  alone_options.stall_tolerance_m = 1e-9;
  FabrikSolver alone(e.limits_model, e.targets, alone_options);
  Posture posture = Posture::rest(m);
  alone.solve(e.positions_m, std::vector<std::uint8_t>{1, 0}, posture);
  const double alone_m = alone.target_distances_m()[0];
  checks["prioritized_strong_as_alone"] =
      check(r.prio.distances_m[0] - alone_m <= e.solver.tolerance_m,
            (r.prio.distances_m[0] - alone_m) * 1e3, e.solver.tolerance_m * 1e3, "mm",
            "strong wrist error minus its error when it is the only target (within the limits)");
  return {{"model", m.name},
          {"algorithms", algorithms_json(e, m, r, false)},
          {"ratios", ratios_json(r)},
          {"checks", checks}};
}

}  // namespace

json run_paper(const PaperOptions& options) {
  const Experiment e = load_experiment(options.experiment);
  const int repeats = options.repeats > 0 ? options.repeats : e.repeats;
  if (e.targets.size() != 2 || e.targets[0].level <= e.targets[1].level)
    throw ConfigError(options.experiment, "/targets",
                      "the paper experiment needs two targets, the first stronger",
                      "list the high-priority wrist first with the higher level");
  const Model& m = *e.model;
  // JT is slow: fewer repetitions give the same median for this deterministic problem.
  const Runs r = run_all(e, e.model, repeats, std::max(5, repeats / 10), true);
  const json geometry = posture_checks(e, r.flat, r.prio);

  json out;
  out["benchmark"] = "paper";
  out["experiment"] = options.experiment;
  out["model"] = m.name;
  out["tolerance_mm"] = e.solver.tolerance_m * 1e3;
  out["geometric_minimum_mm"] = geometry["geometric_minimum_mm"];
  json targets = json::array();
  for (std::size_t i = 0; i < e.targets.size(); ++i)
    targets.push_back(
        {{"point", e.target_names[i]},
         {"level", e.targets[i].level},
         {"position_m", {e.positions_m[i].x(), e.positions_m[i].y(), e.positions_m[i].z()}}});
  out["targets"] = targets;
  out["root_m"] = geometry["root_m"];
  out["segment_fit"] = e.solver.segment_fit == SegmentFit::paper ? "paper" : "rigid";
  out["algorithms"] = algorithms_json(e, m, r, true);
  out["ratios"] = ratios_json(r);
  out["ratios"]["jt_over_fabrik_paper_rule"] = r.jt.median_us() / r.flat_paper.median_us();
  out["ratios"]["jt_over_prioritized_paper_rule"] = r.jt.median_us() / r.prio_paper.median_us();
  out["checks"] = geometry["checks"];
  if (e.limits_model) out["with_limits"] = limits_json(e, repeats);
  bool all = true;
  for (const auto& c : out["checks"]) all = all && c["pass"].get<bool>();
  if (e.limits_model)
    for (const auto& c : out["with_limits"]["checks"]) all = all && c["pass"].get<bool>();
  out["all_checks_pass"] = all;
  return out;
}

namespace {

std::string algorithms_table(const json& r, const json& algorithms) {
  std::string s =
      "algorithm                              median_us    p99_us  iterations  passes  status     "
      "     strong_mm  weak_mm\n";
  char line[256];
  for (const char* name :
       {"fabrik", "fabrik_prioritized", "fabrik_paper_rule", "fabrik_prioritized_paper_rule",
        "jacobian_transpose", "jacobian_transpose_to_fabrik_accuracy"}) {
    if (!algorithms.contains(name)) continue;
    const json& a = algorithms[name];
    const auto& err = a["error_mm"];
    std::snprintf(line, sizeof line, "%-38s %9.2f %9.2f %11d %7d  %-14s %9.2f %8.2f\n", name,
                  a["median_us"].get<double>(), a["p99_us"].get<double>(),
                  a["iterations"].get<int>(), a["passes"].get<int>(),
                  a["status"].get<std::string>().c_str(),
                  err[r["targets"][0]["point"].get<std::string>()].get<double>(),
                  err[r["targets"][1]["point"].get<std::string>()].get<double>());
    s += line;
  }
  return s;
}

std::string ratios_table(const json& ratios) {
  char line[512];
  std::snprintf(line, sizeof line,
                "\nJT / FABRIK             %8.1fx  (paper: 25x)   to FABRIK's accuracy: %5.1fx\n"
                "JT / prioritized FABRIK %8.1fx  (paper: 7x)    to FABRIK's accuracy: %5.1fx\n",
                ratios["jt_over_fabrik"].get<double>(),
                ratios["jt_to_fabrik_accuracy_over_fabrik"].get<double>(),
                ratios["jt_over_prioritized"].get<double>(),
                ratios["jt_to_fabrik_accuracy_over_prioritized"].get<double>());
  return line;
}

std::string checks_table(const json& checks) {
  std::string s;
  char line[256];
  for (const auto& [name, c] : checks.items()) {
    std::snprintf(line, sizeof line, "%-4s %-44s %10.4f %s (limit %g)\n",
                  c["pass"].get<bool>() ? "ok" : "FAIL", name.c_str(), c["value"].get<double>(),
                  c["unit"].get<std::string>().c_str(), c["limit"].get<double>());
    s += line;
  }
  return s;
}

}  // namespace

std::string paper_table(const json& r) {
  char line[256];
  std::snprintf(line, sizeof line,
                "Paper experiment (Moya & Colloud 2013, Fig. 2, in 3D), tolerance %.3g mm, segment "
                "fit %s\n\n",
                r["tolerance_mm"].get<double>(), r["segment_fit"].get<std::string>().c_str());
  std::string s = line;
  s += algorithms_table(r, r["algorithms"]);
  s += ratios_table(r["ratios"]);
  s += "(first column: JT with the experiment's stopping rule, which stops it further from the\n"
       " optimum than FABRIK; second: JT run until its wrist errors are no larger than "
       "FABRIK's)\n\n";
  s += checks_table(r["checks"]);
  if (r.contains("with_limits")) {
    const json& l = r["with_limits"];
    s += "\nWith range-of-motion limits (" + l["model"].get<std::string>() + "):\n\n";
    s += algorithms_table(r, l["algorithms"]);
    s += ratios_table(l["ratios"]);
    s += "(projected onto the limits after every step, JT creeps along them and its own stopping\n"
         " rule does not stop it: the second column is the comparison)\n\n";
    s += checks_table(l["checks"]);
  }
  return s;
}

}  // namespace fabrik::bench
