#include "solver_options_json.hpp"

namespace fabrik {

SolverOptions read_solver_options(const JsonReader& solver, SolverOptions o) {
  solver.only_keys({"tolerance_mm", "stall_tolerance_mm", "max_iterations", "level_passes",
                    "segment_fit", "root", "priorities", "anchor_weight", "subtree_carry",
                    "fallback_carry"});
  o.tolerance_m = solver.get("tolerance_mm", o.tolerance_m * 1e3, 0.0, 1e4) * 1e-3;
  o.stall_tolerance_m =
      solver.get("stall_tolerance_mm", o.stall_tolerance_m * 1e3, 0.0, 1e3) * 1e-3;
  o.max_iterations = static_cast<int>(
      solver.get("max_iterations", static_cast<long long>(o.max_iterations), 1LL, 10000000LL));
  o.level_passes = static_cast<int>(
      solver.get("level_passes", static_cast<long long>(o.level_passes), 1LL, 100000LL));
  o.use_priorities = solver.get("priorities", o.use_priorities);
  o.anchor_weight = solver.get("anchor_weight", o.anchor_weight, 0.0, 1e9);
  o.subtree_carry = solver.get("subtree_carry", o.subtree_carry, 0.0, 100.0);
  o.fallback_carry = solver.get("fallback_carry", o.fallback_carry, 0.0, 100.0);
  if (solver.has("segment_fit"))
    o.segment_fit =
        read_choice<SegmentFit>(solver.at("segment_fit"), "segment fit",
                                {{"paper", SegmentFit::paper}, {"rigid", SegmentFit::rigid}});
  if (solver.has("root"))
    o.root = read_choice<RootMode>(solver.at("root"), "root mode",
                                   {{"fixed", RootMode::fixed}, {"free", RootMode::free}});
  return o;
}

nlohmann::ordered_json solver_options_json(const SolverOptions& o) {
  nlohmann::ordered_json j = nlohmann::ordered_json::object();
  j["tolerance_mm"] = o.tolerance_m * 1e3;
  j["stall_tolerance_mm"] = o.stall_tolerance_m * 1e3;
  j["max_iterations"] = o.max_iterations;
  j["segment_fit"] = o.segment_fit == SegmentFit::rigid ? "rigid" : "paper";
  j["root"] = o.root == RootMode::free ? "free" : "fixed";
  j["priorities"] = o.use_priorities;
  if (o.subtree_carry != 0.0) j["subtree_carry"] = o.subtree_carry;
  if (o.fallback_carry != SolverOptions{}.fallback_carry) j["fallback_carry"] = o.fallback_carry;
  return j;
}

}  // namespace fabrik
