#include "solver_options_json.hpp"

namespace fabrik {

SolverOptions read_solver_options(const JsonReader& solver, SolverOptions o) {
  solver.only_keys({"tolerance_mm", "stall_tolerance_mm", "max_iterations", "level_passes",
                    "segment_fit", "root", "priorities", "anchor_weight"});
  o.tolerance_m = solver.get("tolerance_mm", o.tolerance_m * 1e3, 0.0, 1e4) * 1e-3;
  o.stall_tolerance_m =
      solver.get("stall_tolerance_mm", o.stall_tolerance_m * 1e3, 0.0, 1e3) * 1e-3;
  o.max_iterations = static_cast<int>(
      solver.get("max_iterations", static_cast<long long>(o.max_iterations), 1LL, 10000000LL));
  o.level_passes = static_cast<int>(
      solver.get("level_passes", static_cast<long long>(o.level_passes), 1LL, 100000LL));
  o.use_priorities = solver.get("priorities", o.use_priorities);
  o.anchor_weight = solver.get("anchor_weight", o.anchor_weight, 0.0, 1e9);
  if (solver.has("segment_fit")) {
    const JsonReader fit = solver.at("segment_fit");
    const std::string v = fit.as_string();
    if (v == "paper")
      o.segment_fit = SegmentFit::paper;
    else if (v == "rigid")
      o.segment_fit = SegmentFit::rigid;
    else
      fit.fail("unknown segment fit '" + v + "'", "use \"paper\" or \"rigid\"");
  }
  if (solver.has("root")) {
    const JsonReader root = solver.at("root");
    const std::string v = root.as_string();
    if (v == "fixed")
      o.root = RootMode::fixed;
    else if (v == "free")
      o.root = RootMode::free;
    else
      root.fail("unknown root mode '" + v + "'", "use \"fixed\" or \"free\"");
  }
  return o;
}

}  // namespace fabrik
