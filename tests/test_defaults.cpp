// One owner per default: the tracking defaults live in tracking_settings.hpp (and the daemon's
// in DaemonConfig); config/default.json and the configs `fabrik calibrate` writes state the
// same values, and must load to exactly them.
#include <unistd.h>
#include <catch2/catch.hpp>
#include <filesystem>

#include "calib/calib_template.hpp"
#include "calib/calibrate.hpp"
#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"
#include "leg_subject.hpp"

using namespace fabrik;

namespace {

void check_same_solver(const SolverOptions& a, const SolverOptions& b) {
  CHECK(a.tolerance_m == b.tolerance_m);
  CHECK(a.max_iterations == b.max_iterations);
  CHECK(a.stall_tolerance_m == b.stall_tolerance_m);
  CHECK(a.segment_fit == b.segment_fit);
  CHECK(a.root == b.root);
  CHECK(a.use_priorities == b.use_priorities);
  CHECK(a.level_passes == b.level_passes);
  CHECK(a.anchor_weight == b.anchor_weight);
  CHECK(a.extrapolate == b.extrapolate);
  CHECK(a.fallback_carry == b.fallback_carry);
  CHECK(a.orientation_lever_m == b.orientation_lever_m);
}

// Every setting a config file may leave out, against the built-in default.
void check_defaults(const DaemonConfig& loaded) {
  const DaemonConfig d;
  INFO("config " << loaded.file);
  check_same_solver(loaded.tracker.solver, d.tracker.solver);
  CHECK(loaded.tracker.occlusion.hold_s == d.tracker.occlusion.hold_s);
  CHECK(loaded.tracker.outliers.enabled == d.tracker.outliers.enabled);
  CHECK(loaded.tracker.outliers.floor_m == d.tracker.outliers.floor_m);
  CHECK(loaded.tracker.outliers.moved_m == d.tracker.outliers.moved_m);
  CHECK(loaded.tracker.outliers.relabel_mirrored == d.tracker.outliers.relabel_mirrored);
  CHECK(loaded.tracker.outliers.mirror_ratio == d.tracker.outliers.mirror_ratio);
  CHECK(loaded.tracker.outliers.mirror_floor_m == d.tracker.outliers.mirror_floor_m);
  CHECK(loaded.tracker.outliers.mirror_max_s == d.tracker.outliers.mirror_max_s);
  CHECK(loaded.tracker.confidence.threshold == d.tracker.confidence.threshold);
  CHECK(loaded.tracker.confidence.scale_weight == d.tracker.confidence.scale_weight);
  CHECK(loaded.tracker.smoothing.enabled == d.tracker.smoothing.enabled);
  CHECK(loaded.tracker.smoothing.min_cutoff_hz == d.tracker.smoothing.min_cutoff_hz);
  CHECK(loaded.tracker.smoothing.beta_per_m == d.tracker.smoothing.beta_per_m);
  CHECK(loaded.tracker.smoothing.d_cutoff_hz == d.tracker.smoothing.d_cutoff_hz);
  CHECK(loaded.tracker.quality.rms_m == d.tracker.quality.rms_m);
  CHECK(loaded.tracker.quality.max_m == d.tracker.quality.max_m);
  CHECK(loaded.tracker.cold_start.max_iterations == d.tracker.cold_start.max_iterations);
  CHECK(loaded.tracker.cold_start.after_gap_s == d.tracker.cold_start.after_gap_s);
  CHECK(loaded.input.address == d.input.address);
  CHECK(loaded.input.mode == d.input.mode);
  CHECK(loaded.output.address == d.output.address);
  CHECK(loaded.output.mode == d.output.mode);
  CHECK(loaded.input_m_per_unit == d.input_m_per_unit);
  CHECK(loaded.output_m_per_unit == d.output_m_per_unit);
  CHECK(loaded.output_encoding == d.output_encoding);
  CHECK(loaded.max_payload_bytes == d.max_payload_bytes);
  CHECK(loaded.max_backlog_frames == d.max_backlog_frames);
  CHECK(loaded.stats_interval_s == d.stats_interval_s);
  CHECK(loaded.log_level == d.log_level);
}

}  // namespace

TEST_CASE("A TrackerSetup's solver options are the tracking defaults", "[defaults]") {
  const TrackerSetup setup;
  check_same_solver(setup.solver, tracking_solver_options());
  // ... which are not the bare solver's (the paper's fixed-root experiment).
  CHECK(setup.solver.root == RootMode::free);
  CHECK(SolverOptions{}.root == RootMode::fixed);
}

TEST_CASE("config/default.json states the built-in defaults", "[defaults]") {
  check_defaults(default_daemon_config());
}

TEST_CASE("A config written by calibrate states the built-in defaults", "[defaults]") {
  const test::Subject s;
  const std::string trc = (std::filesystem::temp_directory_path() /
                           ("fabrik_test_defaults_" + std::to_string(getpid()) + ".trc"))
                              .string();
  io::write_trc(trc, s.trial(), "mm");
  const io::MarkerTrial trial = io::read_trial(trc);
  std::filesystem::remove(trc);
  const calib::CalibTemplate t = calib::load_template(test::leg_template(), "leg.json");
  const calib::CalibrationResult r = calib::calibrate(t, trial, "static.trc");
  const DaemonConfig loaded = load_daemon_config(r.config.dump(), "calibrated.json");
  check_defaults(loaded);
}
