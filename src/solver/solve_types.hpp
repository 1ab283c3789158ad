// Inputs and outputs shared by every solver in the library (FABRIK and the
// Jacobian baselines), so they can be swapped and compared on equal terms.
#pragma once

#include <cstdint>
#include <string_view>

namespace fabrik {

// A target pulls one model point towards a measured world position.
struct Target {
  int point = -1;       // index into Model::points
  int level = 0;        // priority level: higher is stronger
  double weight = 1.0;  // relative weight within its level
};

enum class SegmentFit {
  paper,  // Moya & Colloud 2013: translate to the mean candidate, rotate by angle(a, b)
  rigid,  // least-squares rotation of all driving points of the segment
};

enum class RootMode {
  fixed,  // the root base stays where the start posture has it (the paper's experiment)
  free,   // the root segment is placed by its own targets (mocap: the pelvis moves)
};

struct SolverOptions {
  double tolerance_m = 1e-3;         // converged when every visible target is this close
  int max_iterations = 64;           // per solve
  double stall_tolerance_m = 1e-7;   // stalled when no target distance changes more per iteration
  SegmentFit segment_fit = SegmentFit::paper;
  RootMode root = RootMode::fixed;
  bool use_priorities = true;        // false: all levels are solved together, in one pass
  // Passes of one level per visit of the priority loop: the level is revisited
  // until its own targets settle (tolerance or stall), at most this often.
  // 1 is the paper's literal loop, where a weak level can cost the strongest
  // one accuracy in a conflict (tests/test_solver.cpp shows by how much).
  int level_passes = 100;
};

enum class SolveStatus : std::uint8_t {
  converged,       // every visible target within tolerance
  stalled,         // a fixed point: no target moved by stall tolerance (e.g. unreachable)
  max_iterations,  // iteration budget spent while still improving
  no_targets,      // nothing visible to track: posture unchanged
};

inline std::string_view to_string(SolveStatus s) {
  switch (s) {
    case SolveStatus::converged: return "converged";
    case SolveStatus::stalled: return "stalled";
    case SolveStatus::max_iterations: return "max_iterations";
    case SolveStatus::no_targets: return "no_targets";
  }
  return "unknown";
}

struct SolveResult {
  SolveStatus status = SolveStatus::no_targets;
  int iterations = 0;      // of the convergence loop
  int passes = 0;          // forward + backward reaching passes, over all levels
  int visible_targets = 0;
  double rms_m = 0.0;      // over visible targets, unweighted
  double max_m = 0.0;
  int worst_target = -1;   // index into the solver's targets, -1 if none visible
};

}  // namespace fabrik
