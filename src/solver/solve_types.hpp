/// @file
/// Inputs and outputs shared by every solver in the library (FABRIK and the
/// Jacobian baselines), so they can be swapped and compared on equal terms.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace fabrik {

/// A target pulls one model point towards a measured world position.
struct Target {
  int point = -1;       ///< index into Model::points
  int level = 0;        ///< priority level: higher is stronger
  double weight = 1.0;  ///< relative weight within its level
};

/// A target that turns one segment towards a measured world orientation (an
/// IMU or a tracked rigid body, already brought into the segment's frame).
/// It weighs as much as three point targets at `orientation_lever_m` from the
/// segment's base along its axes would: an orientation error of theta radians
/// counts like a point lever * theta away.
struct OrientationTarget {
  int segment = -1;  ///< index into Model::segments
  int level = 0;        ///< priority level, as Target::level
  double weight = 1.0;  ///< relative weight within its level, as Target::weight
};

/// How a reaching pass turns a segment about its base towards the positions its
/// driving points should take.
enum class SegmentFit {
  paper,  ///< Moya & Colloud 2013: translate to the mean candidate, rotate by angle(a, b)
  rigid,  ///< least-squares rotation of all driving points of the segment
};

/// Whether the root segment's base may move.
enum class RootMode {
  fixed,  ///< the root base stays where the start posture has it (the paper's experiment)
  free,   ///< the root segment is placed by its own targets (mocap: the pelvis moves)
};

/// How the convergence loop runs and when it stops; part of a SolverPlan.
struct SolverOptions {
  double tolerance_m = 1e-3;        ///< converged when every visible target is this close
  int max_iterations = 64;          ///< per solve
  double stall_tolerance_m = 1e-6;  ///< stalled when no target moves more (docs/convergence.md)
  SegmentFit segment_fit = SegmentFit::paper;  ///< how each segment is turned in a pass
  RootMode root = RootMode::fixed;             ///< whether the root base may move
  bool use_priorities = true;  ///< false: all levels are solved together, in one pass
  /// Passes of the strongest level per iteration: it is revisited until its
  /// targets settle (tolerance or stall), at most this often, so it ends every
  /// iteration as well met as it can be. 1 is the paper's literal loop.
  int level_passes = 8;
  /// In the pass of a level, targets of stronger levels take part too, with
  /// their weight times this factor: they hold what the stronger levels
  /// reached, so a weak level moves the body mostly where the strong ones
  /// leave it free (their null space, in Baerlocher & Boulic's terms).
  /// 0 disables it (the paper's literal loop, where each level pulls alone):
  /// then a weak level can cost the strongest one accuracy in a conflict.
  /// The Tracker's cold frames take at least 1 (cold_solver_options).
  double anchor_weight = 1000.0;
  /// With joint limits: the targets below a limited joint also pull, with
  /// their weight times this factor, on the segments above it (through
  /// limited joints), held at the joints' current angles. 0 (with fallback_carry 0) is
  /// FABRIK's own rule (a segment feels its children only through their joint points),
  /// whose fixed point can sit far from the constrained least-squares fit on
  /// real data; > 0 costs iterations (see docs/joint-limits.md, "Subtree carry").
  double subtree_carry = 0.0;
  /// With subtree_carry 0 and joint limits, FABRIK's loop can leave a fit it has nearly
  /// reached (a thigh holding one of its three markers turns about its long axis while the
  /// knee hinge follows, growing ~1.2x an iteration to a cycle 0.1-0.2 m off): a solve
  /// whose RMS rises 4 iterations in a row to over 1.25x its lowest takes this carry for
  /// the rest. The Tracker's cold frames take it from the start (cold_solver_options).
  /// 0: never (FABRIK's own rule throughout).
  double fallback_carry = 0.5;
  /// Jump ahead along the convergence loop's steps when they shrink along one direction
  /// (docs/speed.md): with one priority level, kept only when it lowers the
  /// weighted squared distance of the targets. false: FABRIK's own iterations alone.
  bool extrapolate = true;
  /// The lever of orientation targets (see OrientationTarget), metres.
  double orientation_lever_m = 0.1;
};

/// Why `options` cannot run a solve ("tolerance_m must be a finite number, not negative (is
/// nan)", "max_iterations must be at least 1 (is 0)"), or "": every length, weight and carry finite
/// and not negative, the counts at least 1, the orientation lever positive. SolverPlan (and the
/// Tracker) refuse such options at setup.
std::string solver_options_problem(const SolverOptions& options);

/// Why a solve stopped. Every outcome is a value here, never an exception.
enum class SolveStatus : std::uint8_t {
  converged,        ///< every visible target within tolerance
  stalled,          ///< a fixed point: no target moved by stall tolerance (e.g. unreachable)
  max_iterations,   ///< iteration budget spent while still improving
  no_targets,       ///< nothing visible to track: posture unchanged
  size_mismatch,    ///< the inputs do not match the solver's targets or model: posture unchanged
  wrong_workspace,  ///< solve(plan, workspace, ...) with a workspace made for another plan
  /// A visible target, a visible orientation or the start posture holds NaN or an infinity
  /// (or a rotation of zero length): posture unchanged
  non_finite_input,
};

/// The enumerator's name, e.g. "converged" (for logs and reports).
inline std::string_view to_string(SolveStatus s) {
  switch (s) {
    case SolveStatus::converged:
      return "converged";
    case SolveStatus::stalled:
      return "stalled";
    case SolveStatus::max_iterations:
      return "max_iterations";
    case SolveStatus::no_targets:
      return "no_targets";
    case SolveStatus::size_mismatch:
      return "size_mismatch";
    case SolveStatus::wrong_workspace:
      return "wrong_workspace";
    case SolveStatus::non_finite_input:
      return "non_finite_input";
  }
  return "unknown";
}

/// What one solve did and how well the posture meets its visible targets at the end.
struct SolveResult {
  SolveStatus status = SolveStatus::no_targets;  ///< why it stopped
  int iterations = 0;  ///< of the convergence loop
  int passes = 0;      ///< forward + backward reaching passes, over all levels
  int jumps = 0;       ///< extrapolations kept (SolverOptions::extrapolate)
  int visible_targets = 0;  ///< point and orientation targets visible in this solve
  /// Over visible targets, unweighted; an orientation target counts as its
  /// angle times orientation_lever_m.
  double rms_m = 0.0;
  double max_m = 0.0;  ///< the largest distance of a visible target, metres (unweighted)
  /// Index into the solver's targets (point targets first, then orientation
  /// targets), -1 if none visible.
  int worst_target = -1;
};

}  // namespace fabrik
