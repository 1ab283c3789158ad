// `fabrik bench paper`: Moya & Colloud (2013), Figure 2, reproduced in 3D.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>

#include "bench.hpp"
#include "config/json_reader.hpp"
#include "config/model_loader.hpp"
#include "config/resources.hpp"
#include "config/solver_options_json.hpp"
#include "solver/fabrik_solver.hpp"
#include "solver/jacobian_solver.hpp"
#include "stats.hpp"

namespace fabrik::bench {

namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

struct Experiment {
  std::shared_ptr<const Model> model;
  std::vector<Target> targets;
  std::vector<std::string> target_names;
  std::vector<Eigen::Vector3d> positions_m;
  SolverOptions solver;
  int repeats = 1000;
};

Experiment load_experiment(const std::string& path) {
  const json doc = JsonReader::parse(read_config_text(path), path);
  const JsonReader root(doc, path);
  root.only_keys({"format", "description", "model", "units", "targets", "solver", "repeats"});
  Experiment e;
  // The model path is relative to the experiment file (or embedded).
  const std::string model_rel = root.at("model").as_string();
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  const std::string model_path =
      std::filesystem::exists(path) ? (dir / model_rel).string() : model_rel;
  e.model = std::make_shared<const Model>(
      load_model(JsonReader::parse(read_config_text(model_path), model_path), model_path));
  const double scale = metres_per_unit(root.at("units"));
  const JsonReader targets = root.at("targets");
  targets.expect_array();
  for (std::size_t i = 0; i < targets.value().size(); ++i) {
    const JsonReader t = targets.at(i);
    t.only_keys({"point", "position", "level", "weight"});
    const std::string name = t.at("point").as_string();
    const int point = e.model->find_point(name);
    if (point < 0) t.at("point").fail("no point '" + name + "' in the model", "name a model point");
    e.targets.push_back({point, static_cast<int>(t.get("level", 0LL, -1000LL, 1000LL)),
                         t.get("weight", 1.0, 1e-6, 1e6)});
    e.target_names.push_back(name);
    e.positions_m.push_back(t.at("position").as_vec3() * scale);
  }
  e.solver = read_solver_options(root.at("solver"));
  e.repeats = static_cast<int>(root.get("repeats", 1000LL, 1LL, 10000000LL));
  return e;
}

struct Run {
  SolveResult result;
  Posture posture;
  std::vector<double> distances_m;
  std::vector<double> times_us;
};

// Solves from the rest posture `repeats` times (at least `min_seconds` of work
// for slow solvers is not needed: every run is the same problem).
template <class Solver>
Run time_solver(Solver& solver, const Experiment& e, int repeats) {
  Run run;
  const std::vector<std::uint8_t> visible(e.targets.size(), 1);
  const Posture start = Posture::rest(*e.model);
  run.posture = start;
  run.times_us.reserve(static_cast<std::size_t>(repeats));
  for (int i = 0; i < repeats; ++i) {
    std::copy(start.segments.begin(), start.segments.end(), run.posture.segments.begin());
    const auto t0 = Clock::now();
    run.result = solver.solve(e.positions_m, visible, run.posture);
    const auto t1 = Clock::now();
    run.times_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
  }
  const auto d = solver.target_distances_m();
  run.distances_m.assign(d.begin(), d.end());
  return run;
}

json posture_json(const Model& m, const Posture& p) {
  json joints = json::object();
  for (const Joint& j : m.joints) {
    const Eigen::Vector3d x = p.point_world_m(m, j.point);
    joints[j.name] = {x.x(), x.y(), x.z()};
  }
  for (const Point& pt : m.points)
    if (pt.kind == PointKind::end_site) {
      const Eigen::Vector3d x = p.segments[pt.segment].to_world(pt.p_local_m);
      joints[pt.name] = {x.x(), x.y(), x.z()};
    }
  json segments = json::array();  // each segment as its list of point names, base first
  for (const Segment& s : m.segments) {
    json names = json::array();
    for (int k = s.first_point; k < s.first_point + s.point_count; ++k)
      names.push_back(m.points[k].name);
    segments.push_back({{"name", s.name}, {"points", names}});
  }
  return {{"points_m", joints}, {"segments", segments}};
}

json run_json(const Experiment& e, const Run& run) {
  json errors = json::object();
  for (std::size_t i = 0; i < e.targets.size(); ++i)
    errors[e.target_names[i]] = run.distances_m[i] * 1e3;
  return {{"median_us", quantile(run.times_us, 0.5)},
          {"p99_us", quantile(run.times_us, 0.99)},
          {"runs", run.times_us.size()},
          {"status", to_string(run.result.status)},
          {"iterations", run.result.iterations},
          {"passes", run.result.passes},
          {"error_mm", errors},
          {"posture", posture_json(*e.model, run.posture)}};
}

json check(bool pass, double value, double limit, const char* unit, const char* what) {
  return {{"pass", pass}, {"value", value}, {"limit", limit}, {"unit", unit}, {"meaning", what}};
}

double off_line_m(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& u) {
  const Eigen::Vector3d v = p - a;
  return (v - v.dot(u) * u).norm();
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

  SolverOptions flat = e.solver;
  flat.use_priorities = false;
  FabrikSolver fabrik(e.model, e.targets, flat);
  const Run r_flat = time_solver(fabrik, e, repeats);

  SolverOptions prio = e.solver;
  prio.use_priorities = true;
  FabrikSolver prioritized(e.model, e.targets, prio);
  const Run r_prio = time_solver(prioritized, e, repeats);

  // The same two runs with the paper's literal subbase rule, for comparison.
  SolverOptions flat_paper = flat, prio_paper = prio;
  flat_paper.segment_fit = prio_paper.segment_fit = SegmentFit::paper;
  FabrikSolver fabrik_paper(e.model, e.targets, flat_paper);
  const Run r_flat_paper = time_solver(fabrik_paper, e, repeats);
  FabrikSolver prioritized_paper(e.model, e.targets, prio_paper);
  const Run r_prio_paper = time_solver(prioritized_paper, e, repeats);

  // JT is slow: fewer repetitions give the same median for this deterministic problem.
  JacobianSolver jt(e.model, e.targets, flat, {JacobianMethod::transpose, 0.0, 0.2});
  const Run r_jt = time_solver(jt, e, std::max(5, repeats / 10));

  // The same JT, timed to the accuracy FABRIK ends with: it stops when both
  // wrists are at least as close as FABRIK's final errors (tolerance = the
  // worse of them; no stall rule). Its own stall rule above stops it short of
  // that (0.2 mm further from the optimum); the paper compares algorithms at
  // the same tolerance.
  SolverOptions equal = flat;
  equal.tolerance_m = std::max(r_flat.distances_m[0], r_flat.distances_m[1]);
  equal.stall_tolerance_m = 0.0;
  JacobianSolver jt_equal(e.model, e.targets, equal, {JacobianMethod::transpose, 0.0, 0.2});
  const Run r_jt_equal = time_solver(jt_equal, e, std::max(5, repeats / 10));

  // Geometry of the ideal prioritized posture: the chain from the root to
  // the strong wrist straight towards its target.
  const double tol_m = e.solver.tolerance_m;
  const int strong_pt = e.targets[0].point, weak_pt = e.targets[1].point;
  const Eigen::Vector3d root_m = Posture::rest(m).segments[0].base_world_m;
  const Eigen::Vector3d t_strong = e.positions_m[0], t_weak = e.positions_m[1];
  const Eigen::Vector3d u = (t_strong - root_m).normalized();
  double chain_m = 0.0;
  std::vector<int> chain_points;  // the strong wrist and every joint up to the root
  for (int s = m.points[strong_pt].segment, p = strong_pt; s >= 0;
       p = m.segments[s].parent_point, s = m.segments[s].parent) {
    chain_m += (m.points[p].p_local_m).norm();
    chain_points.push_back(p);
  }
  const double strong_min_m = std::max(0.0, (t_strong - root_m).norm() - chain_m);

  // The weak wrist's best error given a straight strong chain: the subbase
  // segment may only twist about u, so the weak shoulder lies on a circle.
  int branch =
      m.points[weak_pt].segment;  // the weak side's segment that hangs off the shared chain
  double weak_arm_m = m.points[weak_pt].p_local_m.norm();
  auto on_chain = [&](int seg) { return m.is_ancestor_or_self(seg, m.points[strong_pt].segment); };
  while (!on_chain(m.segments[branch].parent)) {
    weak_arm_m += m.points[m.segments[branch].parent_point].p_local_m.norm();
    branch = m.segments[branch].parent;
  }
  const int subbase = m.segments[branch].parent;
  const Eigen::Vector3d weak_joint_local = m.points[m.segments[branch].parent_point].p_local_m;
  int strong_child = m.points[strong_pt].segment;  // the strong side's child of the subbase
  while (m.segments[strong_child].parent != subbase) strong_child = m.segments[strong_child].parent;
  const Eigen::Vector3d strong_joint_local =
      m.points[m.segments[strong_child].parent_point].p_local_m;
  double to_subbase_m = 0.0;  // from the root to the subbase's base along the chain
  for (int s = subbase; m.segments[s].parent >= 0; s = m.segments[s].parent)
    to_subbase_m += m.points[m.segments[s].parent_point].p_local_m.norm();
  const Eigen::Vector3d sub_base_m = root_m + to_subbase_m * u;
  const Eigen::Vector3d r_hat = strong_joint_local.normalized();
  const double along = weak_joint_local.dot(r_hat);
  const double radius = (weak_joint_local - along * r_hat).norm();
  const Eigen::Vector3d v = t_weak - (sub_base_m + along * u);
  const double v_par = v.dot(u), v_perp = (v - v_par * u).norm();
  const double weak_min_m = std::max(0.0, std::hypot(v_par, v_perp - radius) - weak_arm_m);

  // Checks.
  const double flat_r = r_flat.distances_m[0], flat_l = r_flat.distances_m[1];
  double straight_m = 0.0;
  for (int p : chain_points)
    straight_m = std::max(straight_m, off_line_m(r_prio.posture.point_world_m(m, p), root_m, u));
  const double prio_strong = r_prio.distances_m[0], prio_weak = r_prio.distances_m[1];
  json checks = json::object();
  checks["flat_balanced"] =
      check(std::abs(flat_r - flat_l) <= tol_m, std::abs(flat_r - flat_l) * 1e3, tol_m * 1e3, "mm",
            "without priorities the two wrist errors are equal (posture centred)");
  checks["prioritized_chain_straight"] = check(
      straight_m <= tol_m, straight_m * 1e3, tol_m * 1e3, "mm",
      "with priorities every joint from the root to the strong wrist lies on the line root-target");
  checks["prioritized_strong_at_minimum"] =
      check(std::abs(prio_strong - strong_min_m) <= tol_m, (prio_strong - strong_min_m) * 1e3,
            tol_m * 1e3, "mm",
            "strong wrist error minus the geometric minimum |target - root| - chain length");
  checks["prioritized_weak_at_constrained_minimum"] =
      check(prio_weak - weak_min_m <= tol_m, (prio_weak - weak_min_m) * 1e3, tol_m * 1e3, "mm",
            "weak wrist error minus the best possible while the strong chain is straight");
  checks["priorities_favour_strong"] =
      check(prio_strong < flat_r, (flat_r - prio_strong) * 1e3, 0.0, "mm",
            "the strong wrist gets closer with priorities than without");
  bool all = true;
  for (const auto& c : checks) all = all && c["pass"].get<bool>();

  const double t_flat = quantile(r_flat.times_us, 0.5), t_prio = quantile(r_prio.times_us, 0.5);
  const double t_jt = quantile(r_jt.times_us, 0.5);
  const double t_jt_equal = quantile(r_jt_equal.times_us, 0.5);
  json out;
  out["benchmark"] = "paper";
  out["experiment"] = options.experiment;
  out["model"] = m.name;
  out["tolerance_mm"] = tol_m * 1e3;
  out["geometric_minimum_mm"] = {{"strong", strong_min_m * 1e3},
                                 {"weak_given_strong", weak_min_m * 1e3}};
  json targets = json::array();
  for (std::size_t i = 0; i < e.targets.size(); ++i)
    targets.push_back(
        {{"point", e.target_names[i]},
         {"level", e.targets[i].level},
         {"position_m", {e.positions_m[i].x(), e.positions_m[i].y(), e.positions_m[i].z()}}});
  out["targets"] = targets;
  out["root_m"] = {root_m.x(), root_m.y(), root_m.z()};
  out["segment_fit"] = e.solver.segment_fit == SegmentFit::paper ? "paper" : "rigid";
  out["algorithms"] = {{"fabrik", run_json(e, r_flat)},
                       {"fabrik_prioritized", run_json(e, r_prio)},
                       {"fabrik_paper_rule", run_json(e, r_flat_paper)},
                       {"fabrik_prioritized_paper_rule", run_json(e, r_prio_paper)},
                       {"jacobian_transpose", run_json(e, r_jt)},
                       {"jacobian_transpose_to_fabrik_accuracy", run_json(e, r_jt_equal)}};
  out["algorithms"]["jacobian_transpose_to_fabrik_accuracy"]["note"] =
      "JT run until both wrist errors are no larger than FABRIK's final ones (tolerance = "
      "FABRIK's worse wrist error, no stall rule); jacobian_transpose uses the experiment's "
      "stopping rule and stops further from the optimum";
  out["ratios"] = {{"jt_over_fabrik", t_jt / t_flat},
                   {"jt_over_prioritized", t_jt / t_prio},
                   {"jt_over_fabrik_paper_rule", t_jt / quantile(r_flat_paper.times_us, 0.5)},
                   {"jt_over_prioritized_paper_rule", t_jt / quantile(r_prio_paper.times_us, 0.5)},
                   {"jt_to_fabrik_accuracy_over_fabrik", t_jt_equal / t_flat},
                   {"jt_to_fabrik_accuracy_over_prioritized", t_jt_equal / t_prio},
                   {"paper_jt_over_fabrik", 25.0},
                   {"paper_jt_over_prioritized", 7.0}};
  out["checks"] = checks;
  out["all_checks_pass"] = all;
  return out;
}

std::string paper_table(const json& r) {
  std::string s;
  char line[256];
  std::snprintf(line, sizeof line,
                "Paper experiment (Moya & Colloud 2013, Fig. 2, in 3D), tolerance %.3g mm, segment "
                "fit %s\n\n",
                r["tolerance_mm"].get<double>(), r["segment_fit"].get<std::string>().c_str());
  s += line;
  s += "algorithm                              median_us    p99_us  iterations  passes  status     "
       "     "
       "strong_mm  weak_mm\n";
  for (const char* name :
       {"fabrik", "fabrik_prioritized", "fabrik_paper_rule", "fabrik_prioritized_paper_rule",
        "jacobian_transpose", "jacobian_transpose_to_fabrik_accuracy"}) {
    const json& a = r["algorithms"][name];
    const auto& err = a["error_mm"];
    std::snprintf(line, sizeof line, "%-38s %9.2f %9.2f %11d %7d  %-14s %9.2f %8.2f\n", name,
                  a["median_us"].get<double>(), a["p99_us"].get<double>(),
                  a["iterations"].get<int>(), a["passes"].get<int>(),
                  a["status"].get<std::string>().c_str(),
                  err[r["targets"][0]["point"].get<std::string>()].get<double>(),
                  err[r["targets"][1]["point"].get<std::string>()].get<double>());
    s += line;
  }
  const json& ratios = r["ratios"];
  std::snprintf(line, sizeof line,
                "\nJT / FABRIK             %8.1fx  (paper: 25x)   to FABRIK's accuracy: %5.1fx\n"
                "JT / prioritized FABRIK %8.1fx  (paper: 7x)    to FABRIK's accuracy: %5.1fx\n",
                ratios["jt_over_fabrik"].get<double>(),
                ratios["jt_to_fabrik_accuracy_over_fabrik"].get<double>(),
                ratios["jt_over_prioritized"].get<double>(),
                ratios["jt_to_fabrik_accuracy_over_prioritized"].get<double>());
  s += line;
  s += "(first column: JT with the experiment's stopping rule, which stops it further from the\n"
       " optimum than FABRIK; second: JT run until its wrist errors are no larger than "
       "FABRIK's)\n\n";
  for (const auto& [name, c] : r["checks"].items()) {
    std::snprintf(line, sizeof line, "%-4s %-40s %10.4f %s (limit %g)\n",
                  c["pass"].get<bool>() ? "ok" : "FAIL", name.c_str(), c["value"].get<double>(),
                  c["unit"].get<std::string>().c_str(), c["limit"].get<double>());
    s += line;
  }
  return s;
}

}  // namespace fabrik::bench
