// Numbers that agree: calibrate's fit figures are `fabrik solve`'s on the
// same frames; frames are named by the source's frame numbers; a .mot's
// times are the source's own, whatever frame and time the source starts at.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "calib/calibrate.hpp"
#include "config/daemon_config.hpp"
#include "eval/eval.hpp"
#include "io/opensim_table.hpp"
#include "leg_subject.hpp"
#include "offline/solve_trial.hpp"
#include "temp_file.hpp"
#include "tools/synth.hpp"

using namespace fabrik;
using nlohmann::json;

namespace {

// The figures of both, side by side.
void check_fit_is_solve(const calib::CalibrationResult& r, const io::MarkerTrial& trial) {
  const DaemonConfig config = load_daemon_config(r.config.dump(), "calibrated.json");
  const json summary = solution_summary(solve_trial(config, trial));
  const json& res = summary["residual_mm"];
  INFO("calibrate: RMS " << r.fit_rms_mean_m * 1e3 << " mm (worst frame "
                         << r.fit_rms_worst_frame_m * 1e3 << "), max " << r.fit_max_m * 1e3
                         << " mm (" << r.fit_max_marker << ", frame " << r.fit_max_frame
                         << "); solve: " << res.dump());
  CHECK(r.fit_rms_mean_m * 1e3 == Approx(res["rms_mean"].get<double>()).epsilon(1e-12));
  CHECK(r.fit_rms_worst_frame_m * 1e3 == Approx(res["rms_max"].get<double>()).epsilon(1e-12));
  CHECK(r.fit_max_m * 1e3 == Approx(res["max"].get<double>()).epsilon(1e-12));
  CHECK(r.fit_max_marker == res["max_marker"].get<std::string>());
  CHECK(r.fit_max_frame == res["max_frame"].get<long long>());
  CHECK(r.fit_outlier_samples == summary["outliers"]["samples"].get<int>());
}

// The leg subject's static trial from frame 23, with one marker 6 mm off in
// frame 30 (a clear worst frame, away from RTHI's gap in frames 25-26) and
// some sway.
io::MarkerTrial leg_static_from_23() {
  io::MarkerTrial t = test::Subject().trial();
  t.first_frame = 23;
  for (std::size_t f = 0; f < t.frames(); ++f)
    for (std::size_t m = 0; m < t.markers(); ++m)
      if (t.at(f, m).allFinite()) t.at(f, m).x() += 1e-3 * std::sin(0.7 * static_cast<double>(f) + static_cast<double>(m));
  t.at(7, 3).y() += 6e-3;  // RTHI
  return t;
}

}  // namespace

TEST_CASE("calibrate's fit figures are fabrik solve's on the same frames, named by the file's "
          "frame numbers",
          "[numbers][calib]") {
  const io::MarkerTrial trial = leg_static_from_23();
  const calib::CalibrationResult r = calib::calibrate(
      calib::load_template(test::leg_template(), "leg.json"), trial, "static.trc");
  check_fit_is_solve(r, trial);
  CHECK(r.fit_max_marker == "RTHI");
  CHECK(r.fit_max_frame == 30);
  const std::string report = calib::calibration_report(r);
  CHECK_THAT(report, Catch::Contains("mean over frames of each frame's RMS, as fabrik solve"));
  CHECK_THAT(report, Catch::Contains("(RTHI, frame 30)"));
}

TEST_CASE("subject01_static: calibrate's figures are solve's (skipped without ../shared/data)",
          "[numbers][calib][data]") {
  const std::string path = std::string(FABRIK_SHARED_DATA_DIR) + "/subject01_static.trc";
  if (!std::filesystem::exists(path)) {
    WARN("SKIPPED: " << path << " is absent (real data lives in ../shared/data)");
    return;
  }
  const io::MarkerTrial trial = io::read_trial(path);
  const calib::CalibrationResult r = calib::calibrate(
      calib::load_template_file(std::string(FABRIK_SOURCE_DIR) + "/config/templates/gait2354.json"),
      trial, path);
  check_fit_is_solve(r, trial);
}

namespace {

// 0.3 s at 100 Hz of the default config's model, no noise.
io::MarkerTrial default_model_trial() {
  const tools::SynthSetup setup =
      tools::load_synth_setup(std::string(FABRIK_SOURCE_DIR) + "/config/default.json");
  tools::SynthOptions o;
  o.seconds = 0.3;
  o.noise_mm = 0.0;
  return tools::make_synth_trial(setup, o).markers;
}

// The trial written as TRC with its Time column replaced by `times` (text,
// as other writers round them) and its frames numbered from `first_frame`.
io::MarkerTrial as_trc_with_times(io::MarkerTrial trial, int first_frame, double rate_hz,
                                  const std::vector<std::string>& times) {
  trial.first_frame = first_frame;
  trial.rate_hz = rate_hz;
  test::TempFile trc(".trc");
  io::write_trc(trc.path(), trial, "mm");
  std::ifstream in(trc.path());
  std::string line, text;
  int row = 0;
  for (int n = 1; std::getline(in, line); ++n) {
    if (n > 6 && !line.empty()) {  // data rows: Frame#, Time, ...
      const std::size_t a = line.find('\t'), b = line.find('\t', a + 1);
      line = line.substr(0, a + 1) + times.at(row++) + line.substr(b);
    }
    text += line + "\n";
  }
  in.close();
  std::ofstream(trc.path()) << text;
  return io::read_trial(trc.path());
}

std::vector<std::string> times_text(double first_s, double rate_hz, std::size_t n, int decimals) {
  std::vector<std::string> out;
  for (std::size_t k = 0; k < n; ++k) {
    std::ostringstream s;
    s.setf(std::ios::fixed);
    s.precision(decimals);
    s << "  " << first_s + static_cast<double>(k) / rate_hz;
    out.push_back(s.str());
  }
  return out;
}

}  // namespace

TEST_CASE(".mot times are the source's own: frame 23 at 0.23 s, frame 1 at 0 s, rounded "
          "times, a clock off the frame grid",
          "[numbers][offline]") {
  const DaemonConfig config = default_daemon_config();
  const io::MarkerTrial base = default_model_trial();
  const std::size_t n = base.frames();
  struct Case {
    const char* what;
    int first_frame;
    double rate_hz, first_s;
    double grid_frames;  // the first time in frame periods when on the grid, else NaN
  };
  for (const Case& c : {Case{"rajagopal_run: frame 23 at 0.23 s", 23, 100.0, 0.23, 23.0},
                        Case{"OpenSim's own: frame 1 at 0 s", 1, 60.0, 0.0, 0.0},
                        Case{"rounded: frame 5 at 0.066667 s (60 Hz)", 5, 60.0, 4.0 / 60.0, 4.0},
                        Case{"off the grid: frame 1 at 0.005 s", 1, 100.0, 0.005, NAN}}) {
    INFO(c.what);
    const io::MarkerTrial trial =
        as_trc_with_times(base, c.first_frame, c.rate_hz, times_text(c.first_s, c.rate_hz, n, 6));
    const TrialSolution s = solve_trial(config, trial);
    const io::OpenSimTable t = angles_table(s);
    REQUIRE(t.rows == n);
    for (std::size_t k = 0; k < n; ++k) {
      INFO("row " << k);
      CHECK(t.time_s[k] == Approx(c.first_s + static_cast<double>(k) / c.rate_hz).margin(1e-9));
    }
    // On the frame grid, exactly (n + k) / rate, however the file rounded them.
    if (!std::isnan(c.grid_frames)) CHECK(t.time_s[2] == (c.grid_frames + 2.0) / c.rate_hz);
    // The joint centres' TRC carries the same frame numbers and times.
    test::TempFile joints(".trc");
    write_trial_file(joints.path(), s.joints);
    const io::MarkerTrial back = io::read_trial(joints.path());
    CHECK(back.first_frame == c.first_frame);
    CHECK(back.file_time_s(0) == Approx(c.first_s).margin(1e-9));
  }
}

TEST_CASE("Reports name frames by the file's frame numbers: solve's summary, eval walk and "
          "eval angles",
          "[numbers][eval]") {
  const DaemonConfig config = default_daemon_config();
  io::MarkerTrial trial = default_model_trial();
  trial.first_frame = 23;
  const int lasi = trial.find("LASI");
  REQUIRE(lasi >= 0);
  trial.at(12, static_cast<std::size_t>(lasi)).x() += 0.03;  // the worst frame: index 12, frame 35
  const TrialSolution s = solve_trial(config, trial);
  const json summary = solution_summary(s);
  CHECK(summary["residual_mm"]["max_frame"] == 35);

  const eval::WalkReport w = eval::eval_walk(config, trial);
  CHECK(w.max_frame == 35);
  CHECK_THAT(eval::walk_table(w), Catch::Contains(", frame 35)"));
  CHECK(eval::walk_json(w)["max_frame"] == 35);

  // A reference of the truth itself at the trial's own times.
  io::OpenSimTable ref = io::coordinates_table(s.coordinate_names, true);
  const std::size_t nc = s.coordinate_names.size();
  for (std::size_t f = 0; f < trial.frames(); ++f) {
    std::vector<double> row(s.coordinates.begin() + f * nc, s.coordinates.begin() + (f + 1) * nc);
    ref.add_row(trial.file_time_s(f), row);
  }
  const eval::AngleReport a = eval::eval_angles(config, trial, ref, "self.mot");
  CHECK(a.time_s.size() == trial.frames());
  CHECK(a.residual_max_frame == 35);
  REQUIRE_FALSE(a.frame_numbers.empty());
  CHECK(a.frame_numbers.front() == 23);
  CHECK_THAT(eval::angles_table(a), Catch::Contains(", frame 35)"));
  CHECK(eval::angles_json(a)["residual_mm"]["max_frame"] == 35);
}
