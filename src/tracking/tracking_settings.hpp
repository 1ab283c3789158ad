/// @file
/// The settings of a Tracker (tracker.hpp), each with its default: the one owner of the
/// tracking defaults. A daemon config (config/default.json) states the same values; a test
/// checks that it loads to exactly these.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "../solver/solve_types.hpp"

namespace fabrik {

/// The solver options of tracking (fabrikd, `fabrik solve`, a TrackerSetup): a pelvis that moves
/// (free root), multi-marker segments fitted rigidly, 0.1 mm tolerances and 50 iterations a warm
/// frame. SolverOptions' own defaults are the bare solver's (the paper's fixed-root experiment).
inline SolverOptions tracking_solver_options() {
  SolverOptions o;
  o.root = RootMode::free;
  o.segment_fit = SegmentFit::rigid;
  o.tolerance_m = 0.1e-3;
  o.stall_tolerance_m = 0.1e-3;
  o.max_iterations = 50;
  return o;
}

struct SensorTarget {
  std::string sensor;  ///< name in the stream
  int segment = -1;    ///< index into Model::segments
  int level = 0;       ///< priority level, as for markers
  double weight = 1.0;
  Eigen::Quaterniond q_segment_sensor{Eigen::Quaterniond::Identity()};
};

struct SensorSetup {
  std::vector<SensorTarget> sensors;
  Eigen::Quaterniond q_world_sensors{Eigen::Quaterniond::Identity()};
};

struct OutlierSettings {
  bool enabled = true;
  /// A residual at or below this is never an outlier (metres): well beyond the soft-tissue
  /// artefact of a good fit (OpenSim's guidance: max under 2-4 cm).
  double floor_m = 0.060;
  /// Nor one at or below this multiple of the median residual of the other measured markers:
  /// when every marker fits worse (fast motion, a poor calibration), the bar rises with them.
  double median_factor = 8.0;
  /// A candidate moved when its distances to most of its measured neighbours are off by
  /// more than this (metres): beyond the few centimetres skin markers move over bone in
  /// fast movement, well within what a swap, ghost or stray zero does.
  double moved_m = 0.030;
  int max_per_frame = 3;  ///< markers left out per frame at most (one extra solve each)
  int min_markers = 6;    ///< measured markers a frame needs before any is judged
  bool relabel_swaps = true;
};

struct QualitySettings {
  double rms_m = 0.020;  ///< per-frame RMS over the markers that took part in the solve
  double max_m = 0.040;  ///< any one of them
};

enum class FitQuality : std::uint8_t { none, good, poor };

inline std::string_view to_string(FitQuality q) {
  switch (q) {
    case FitQuality::none:
      return "none";
    case FitQuality::good:
      return "good";
    case FitQuality::poor:
      return "poor";
  }
  return "none";
}

struct ColdStartSettings {
  int max_iterations = 500;  ///< the cold frame's budget (a warm frame has solver.max_iterations)
  /// A frame this long after the last one with a measured marker starts cold (seconds).
  double after_gap_s = 0.5;
  bool align = true;  ///< turn and move the rest posture onto the visible markers first
};

struct PredictionSettings {
  bool enabled = false;
  /// Priority level and weight of the predicted rotations (orientation
  /// targets). The daemon config puts them on the weakest marker level with
  /// weight 0.05: a pull that markers on the same level outweigh, which takes
  /// no extra priority pass (a level of their own below the markers' costs one
  /// and, where markers of children constrain the segment, leaves it nothing).
  int level = 0;
  double weight = 0.05;
  /// The relative angular velocity at the start of a gap decays with this time
  /// constant, so the prediction turns at most velocity * decay and then holds
  /// (0: hold from the start).
  double velocity_decay_s = 0.1;
  /// Velocities are differences over this much of the recent past (at least
  /// one frame): long enough to average marker noise, short enough to follow.
  double velocity_window_s = 0.05;
  /// A returning marker's target moves from where the prediction had it to
  /// its measurement at most this fast, so the posture does not jump.
  double return_speed_m_per_s = 0.2;
  /// Donor markers for the reported fill (not the solve): candidates ranked by
  /// the spread of their distance to the marker, triples averaged, their
  /// triangles no flatter than min_sine, weights 1 / max(score, floor)^2; at
  /// most this many gaps start choosing per frame (the rest take the
  /// skeleton's fill), which bounds a frame's cost.
  bool donors = true;
  int donor_candidates = 8;
  int donor_triples = 3;
  double donor_min_sine = 0.2;
  double donor_score_floor_m = 3e-4;
  int donor_choices_per_frame = 4;
  /// Donors come from segments at most this many joints from the marker's (0:
  /// its own): a marker elsewhere that looked steady for a moment is not trusted.
  int donor_max_joints = 2;
  /// Where the skeleton competes, a triple's weight falls as a Gaussian of its
  /// distance from the skeleton's fill, in this many of their combined scores.
  double donor_gate = 3.0;
};

/// A named measured marker that pulls one model point.
struct MarkerTarget {
  std::string marker;  ///< name in the marker stream
  int point = -1;      ///< index into Model::points
  int level = 0;       ///< priority level, higher is stronger
  double weight = 1.0;
};

struct OcclusionPolicy {
  /// An occluded marker's last measured position keeps pulling its point for
  /// this long, as a target of `hold_level`; 0 turns holding off.
  double hold_s = 0.0;
  int hold_level = -1;
};

}  // namespace fabrik
