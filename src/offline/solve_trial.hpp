// Offline tracking of a recorded trial through the same Tracker (and so the
// same targets, priorities, occlusion policy and solver settings) as fabrikd.
#pragma once

#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"
#include "io/opensim_table.hpp"
#include "io/orientation_table.hpp"
#include "tracking/tracker.hpp"

namespace fabrik {

// A tracked marker that the trial misses in most of its frames.
struct MostlyMissing {
  std::string marker;
  std::size_t missing_frames = 0;
  std::size_t zero_frames = 0;  // of them, exact (0, 0, 0) samples read as missing
};

// Samples of one marker filled by the two-sided fill: frames [first, end)
// (indices), and how ("donors" or "skeleton", two_sided_fill.hpp).
struct FilledRun {
  std::string marker;
  std::size_t first = 0, end = 0;
  std::string method;
};

struct TrialSolution {
  io::MarkerTrial joints;  // joint centres per frame (metres), solved on `markers` offline
  // The tracked markers per frame (metres): the samples as measured (after a prefilter), and
  // where one is missing between or beside measured samples, the two-sided fill
  // (two_sided_fill.hpp); NaN for a marker never measured.
  io::MarkerTrial markers;
  // The model's markers per frame (metres), as the Tracker fitted them (its prediction where
  // occluded): what fabrikd publishes live.
  io::MarkerTrial model_markers;
  std::vector<FilledRun> filled;  // by marker, then by frame
  std::vector<double> rms_m;                  // per frame, over measured markers
  std::vector<double> max_m;                  // per frame
  std::vector<int> worst;                     // per frame: index into markers.labels, -1 if none
  std::vector<double> solve_us;               // per frame
  std::vector<int> iterations;                // per frame
  std::vector<std::string> status;            // per frame, the solver's stop reason
  std::vector<int> measured;                  // per frame: tracked markers with a measurement
  // Frames before the first with a measured marker or sensor, and from one past the last
  // (`end_measured`): no pose (NaN joints, model markers and coordinates; the .mot has
  // rows [first_measured, end_measured) only).
  std::size_t first_measured = 0, end_measured = 0;
  // Whether the joint centres and coordinates were solved again on `markers` (some gap was
  // filled): the residual, outlier and quality figures and `model_markers` stay the causal
  // pass's, as fabrikd tracks live.
  bool solved_on_filled_markers = false;
  // Per frame and marker [frame * markers + i]: left out of the solve as an outlier (or
  // relabelled as a swap: outlier_filter.hpp).
  std::vector<std::uint8_t> outlier;
  std::vector<int> outlier_count;  // per frame
  std::vector<FitQuality> quality;  // per frame: residual.quality against config.quality
  // Tracked markers the trial lacks entirely: not among its labels, or never measured.
  std::vector<std::string> missing_in_trial;
  // Tracked markers missing in more than half of the frames (those never measured included).
  std::vector<MostlyMissing> mostly_missing;
  std::vector<std::string> ignored_in_trial;  // trial labels that are not tracked
  // The model's named coordinates (Model::coordinates): name, whether it is a
  // rotation (else a translation), and per frame [frame * names + c] its value
  // in radians or metres.
  std::vector<std::string> coordinate_names;
  std::vector<std::uint8_t> coordinate_is_rotation;
  std::vector<double> coordinates;
  // Orientation sensors: per frame, the RMS angle between the measured
  // sensors' segment rotations and the tracked ones (radians; NaN when none
  // was measured) and the sensors measured; the config's sensors the table
  // lacks (no column, or no usable cell at any frame, as markers never
  // measured); table columns that are no sensor of the config.
  std::vector<double> sensor_rms_rad;
  std::vector<int> sensors_measured;
  std::vector<std::string> sensors_missing_in_table;
  std::vector<std::string> ignored_in_table;
};

// `progress(frame, frames)` is called now and then (may be empty).
// `orientations` (may be null) feeds the config's sensors, joined on time:
// each marker frame takes the table's orientations at its file time
// (MarkerTrial::file_time_s, interpolated). A trial without markers (no labels) is tracked
// on the table's rows instead, at the table's times and rate.
// `on_frame(f, time_s, tracker, result)` (may be empty) sees each frame's result as it is
// tracked, as the daemon would publish it (`fabrik view --trial` encodes poses from it).
// `pass`: `offline` solves the joint centres and coordinates again on the gap-filled markers
// (TrialSolution::solved_on_filled_markers); `live` keeps the causal pass's, as fabrikd
// publishes them (for an evaluation of the live path, or a caller that needs only on_frame).
using TrackedFrameHook =
    std::function<void(std::size_t, double, const Tracker&, const TrackResult&)>;
enum class TrialPass { offline, live };
TrialSolution solve_trial(const DaemonConfig& config, const io::MarkerTrial& trial,
                          const std::function<void(std::size_t, std::size_t)>& progress = {},
                          const io::OrientationTable* orientations = nullptr,
                          const TrackedFrameHook& on_frame = {},
                          TrialPass pass = TrialPass::offline);

// Frames, residual RMS mean and max, worst marker, solve time quantiles. Frames without any
// measured marker have no residual: they are left out of the residual figures and counted
// (frames_without_markers). Frames are named by the source's frame numbers (max_frame).
nlohmann::json solution_summary(const TrialSolution& s);

// The coordinates as an OpenSim Coordinates table (.mot): rotations in
// degrees (inDegrees=yes), translations in metres, at the source's own times
// (MarkerTrial::file_time_s).
io::OpenSimTable angles_table(const TrialSolution& s);

// The filled samples as CSV, one run a line: marker, first and last frame
// number and time as the trial's file counts them, samples.
void write_filled_csv(const std::string& path, const TrialSolution& s, const io::MarkerTrial& trial);

// Samples farther than `max_abs_coordinate_m` from the origin on any axis become missing, as
// fabrikd takes them as occluded (input.max_abs_coordinate_mm): 1e300 in a file is not a
// measurement. Returns how many samples were dropped.
std::size_t drop_implausible_samples(io::MarkerTrial& trial, double max_abs_coordinate_m);

// Writes a trial as .trc (mm) or .csv (header time + name_x/_y/_z in mm).
void write_trial_file(const std::string& path, const io::MarkerTrial& trial);

}  // namespace fabrik
