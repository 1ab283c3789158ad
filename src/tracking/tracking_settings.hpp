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

/// An orientation sensor (an IMU or a tracked rigid body) fixed to one segment: it turns that
/// segment as an orientation target of the solver.
struct SensorTarget {
  std::string sensor;   ///< name in the stream
  int segment = -1;     ///< index into Model::segments
  int level = 0;        ///< priority level, as for markers
  double weight = 1.0;  ///< relative weight within its level
  /// The sensor's frame in its segment's frame (found by calibration).
  Eigen::Quaterniond q_segment_sensor{Eigen::Quaterniond::Identity()};
};

/// The orientation sensors of a Tracker. A sensor measuring q_sensors_sensor makes its segment's
/// desired world rotation q_world_sensors * q_sensors_sensor * q_segment_sensor^-1.
struct SensorSetup {
  std::vector<SensorTarget> sensors;  ///< in the order Tracker::track takes their rotations
  /// The sensors' world (a magnetic/gravity frame for an IMU, the mocap system's for a rigid
  /// body) in the model's world: an axis change, then a heading about the vertical.
  Eigen::Quaterniond q_world_sensors{Eigen::Quaterniond::Identity()};
};

/// Leaving out markers that do not fit (swaps, ghosts, stray zeros): the worst marker beyond
/// the bars below is left out and the frame solved again, at most max_per_frame times.
struct OutlierSettings {
  bool enabled = true;  ///< false: every measured marker takes part
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
  /// Two markers left out that each fit the other's model point are a label swap: they are
  /// put back with their labels exchanged (TrackResult::relabelled_from).
  bool relabel_swaps = true;
  /// Left/right swaps of whole limbs (a markerless pipeline's keypoints jumping to the other
  /// leg): before the solve, each left/right pair of markers (TrackerSetup::mirror_pairs, or
  /// pairs found from the names: R/L, Right/Left, r_/l_ as prefix or suffix) both measured is
  /// relabelled when its mirrored assignment fits the frame's predicted posture far better
  /// (docs/filtering.md). Never on a cold frame (nothing to predict from).
  bool relabel_mirrored = true;
  /// The mirrored assignment is taken when its distance to the predicted points (summed over
  /// the pair) is below this fraction of the labelled one's ...
  double mirror_ratio = 0.25;
  /// ... and the labelled one's mean distance exceeds this (metres): above the few centimetres
  /// a keypoint jitters and a limb moves in a frame at walking speed, below the 0.15-0.3 m
  /// between left and right hips, knees and ankles.
  double mirror_floor_m = 0.050;
  /// A pair is mirrored for at most this long at a stretch (seconds); after that its labels are
  /// taken as they come until its mirror stops fitting better. Swaps last a few frames; a
  /// posture that started from swapped labels (a cold frame has nothing to judge against)
  /// would otherwise keep every later, correct frame mirrored.
  double mirror_max_s = 0.5;
};

/// Per-marker confidence (a markerless pipeline's keypoint likelihood, 0-1), given to
/// Tracker::track: a marker below `threshold` is occluded; above it, its confidence scales its
/// weight within its level.
struct ConfidenceSettings {
  /// Below this a marker is occluded. 0.3 is Pose2Sim's default likelihood threshold for
  /// triangulation (Config.toml, `likelihood_threshold_triangulation = 0.3`).
  double threshold = 0.3;
  bool scale_weight = true;  ///< false: a marker above the threshold pulls with its full weight
};

/// A light causal filter of the measured positions before the solve: a One Euro filter (Casiez,
/// Roussel and Vogel, CHI 2012) per marker, an exponential smoother whose cutoff rises with the
/// filtered speed, so a still marker is smoothed hard and a moving one lags little. Off by
/// default (existing configs behave as before); docs/filtering.md has the measured lag and
/// jitter at these defaults.
struct SmoothingSettings {
  bool enabled = false;  ///< false: measurements go to the solver as they are
  /// Cutoff of a still marker (Hz): lower is smoother at rest, with more lag when slow.
  double min_cutoff_hz = 1.0;
  /// Cutoff growth with speed (Hz per m/s, i.e. 1/m): higher lags less in fast movement.
  double beta_per_m = 40.0;
  double d_cutoff_hz = 1.0;  ///< cutoff of the speed estimate the cutoff follows (Hz)
};

/// The bars of a good fit (FitQuality), metres; markers beyond max_m are reported
/// (TrackResult::beyond).
struct QualitySettings {
  double rms_m = 0.020;  ///< per-frame RMS over the markers that took part in the solve
  double max_m = 0.040;  ///< any one of them
};

/// How well a frame fits, judged against QualitySettings: `none` when no measured marker took
/// part (nothing to judge), `good` when the RMS and the largest residual are within their
/// bars, `poor` otherwise.
enum class FitQuality : std::uint8_t { none, good, poor };

/// The enumerator's name: "none", "good" or "poor".
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

/// The first frame, and a frame after a long gap, start from the rest posture (cold) rather
/// than from the previous frame's result (warm).
struct ColdStartSettings {
  int max_iterations = 500;  ///< the cold frame's budget (a warm frame has solver.max_iterations)
  /// A frame this long after the last one with a measured marker starts cold (seconds).
  double after_gap_s = 0.5;
  bool align = true;  ///< turn and move the rest posture onto the visible markers first
};

/// Live gap filling: while some of a segment's markers are occluded, it is pulled weakly towards
/// the rotation relative to its parent that the recent past predicts, and occluded markers are
/// reported where the prediction (or donor markers) put them.
struct PredictionSettings {
  bool enabled = false;  ///< false: no prediction, an occluded marker stops pulling (unless held)
  /// Priority level and weight of the predicted rotations (orientation
  /// targets). The daemon config puts them on the weakest marker level with
  /// weight 0.05: a pull that markers on the same level outweigh, which takes
  /// no extra priority pass (a level of their own below the markers' costs one
  /// and, where markers of children constrain the segment, leaves it nothing).
  int level = 0;
  double weight = 0.05;  ///< relative weight of the predicted rotations within `level`
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
  int donor_candidates = 8;  ///< candidates per marker: those whose distance to it varied least
  int donor_triples = 3;     ///< triples of candidates averaged, the best scored
  /// A triple is used only where the sine of its triangle's angle at its first marker is at least
  /// this (flatter triangles give no reliable frame).
  double donor_min_sine = 0.2;
  /// Scores (metres: how far holding in the triple's frame missed the marker in the recent past)
  /// below this count as this in the weights, so no near-zero score takes all the weight.
  double donor_score_floor_m = 3e-4;
  int donor_choices_per_frame = 4;  ///< gaps that may start choosing donors in one frame
  /// Donors come from segments at most this many joints from the marker's (0:
  /// its own): a marker elsewhere that looked steady for a moment is not trusted.
  int donor_max_joints = 2;
  /// Where the skeleton competes, a triple's weight falls as a Gaussian of its
  /// distance from the skeleton's fill, in this many of their combined scores.
  double donor_gate = 3.0;
};

/// A named measured marker that pulls one model point.
struct MarkerTarget {
  std::string marker;   ///< name in the marker stream
  int point = -1;       ///< index into Model::points
  int level = 0;        ///< priority level, higher is stronger
  double weight = 1.0;  ///< relative weight within its level
};

/// What an occluded marker does: by default it stops pulling at once.
struct OcclusionPolicy {
  /// An occluded marker's last measured position keeps pulling its point for
  /// this long, as a target of `hold_level`; 0 turns holding off.
  double hold_s = 0.0;
  int hold_level = -1;  ///< priority level of held positions (daemon config: below every marker)
};

}  // namespace fabrik
