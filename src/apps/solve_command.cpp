#include "solve_command.hpp"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>

#include "common/ascii_case.hpp"
#include "common/device_path.hpp"
#include "common/format_number.hpp"
#include "common/safe_text.hpp"
#include "config/closest_names.hpp"
#include "io/output_file.hpp"
#include "offline/marker_match.hpp"
#include "offline/prefilter.hpp"
#include "offline/solve_trial.hpp"
#include "offline/subject_markers.hpp"
#include "read_recording.hpp"
#include "tools/cli_checks.hpp"
#include "tools/distinct_files.hpp"
#include "tools/run_command.hpp"

namespace fabrik::apps {

namespace {

constexpr const char* kAllowMissingMarkers = "--allow-missing-markers";

struct SolveOptions {
  std::string config, input, output, markers_output, model_markers_output, report, angles,
      orientations, subject;
  bool quiet = false, keep_zeros = false, allow_missing_markers = false;
  double filter_hz = 0.0;  // 0: the trial as recorded
};

void progress_bar(std::size_t done, std::size_t total) {
  const int width = 40;
  const int filled = total ? static_cast<int>(width * done / total) : width;
  std::fprintf(stderr, "\r  [%.*s%*s] %zu/%zu frames", filled,
               "########################################", width - filled, "", done, total);
  if (done == total) std::fputc('\n', stderr);
}

void run(const SolveOptions& o) {
  // --markers to a stream (/dev/null, to discard; a pipe) has no list of filled runs: a
  // FILE.filled.csv beside it would be a regular file (in /dev, for /dev/null or /dev/stdout).
  const std::string filled_csv = o.markers_output.empty() || is_stream(o.markers_output)
                                     ? ""
                                     : o.markers_output + ".filled.csv";
  // Before the solve, which can take minutes: what the outputs would be is known now.
  const std::vector<tools::NamedFile> files = {{"--config", o.config, false},
                                               {"--input", o.input, false},
                                               {"--orientations", o.orientations, false},
                                               {"--output", o.output},
                                               {"--markers", o.markers_output},
                                               {"--markers' FILE.filled.csv", filled_csv},
                                               {"--model-markers", o.model_markers_output},
                                               {"--report", o.report},
                                               {"--angles", o.angles}};
  // The extension says what is written; a stream (/dev/null, to discard; /dev/stdout, a pipe)
  // has none to say: it takes a TRC and an OpenSim table.
  const auto require_trc_or_csv = [](const char* option, const std::string& path) {
    if (!has_suffix_ci(path, ".trc") && !has_suffix_ci(path, ".csv"))
      throw std::invalid_argument(std::string(option) + ": '" + path +
                                  "': unknown output format: use .trc or .csv");
  };
  if (!is_stream(o.output)) require_trc_or_csv("--output", o.output);
  if (!o.markers_output.empty() && !is_stream(o.markers_output))
    require_trc_or_csv("--markers", o.markers_output);
  if (!o.model_markers_output.empty() && !is_stream(o.model_markers_output))
    require_trc_or_csv("--model-markers", o.model_markers_output);
  if (!o.angles.empty() && !is_stream(o.angles) && !has_suffix_ci(o.angles, ".mot") &&
      !has_suffix_ci(o.angles, ".sto"))
    throw std::invalid_argument("--angles: '" + o.angles +
                                "': an OpenSim Coordinates table is written: use .mot (or .sto)");
  tools::require_usable_outputs(files);  // after the names: no file is tried for a refused one
  const DaemonConfig config = subject_config(
      o.config.empty() ? default_daemon_config() : load_daemon_config_file(o.config), o.subject);
  if (o.input.empty() && o.orientations.empty())
    throw std::runtime_error("give --input (markers), --orientations (sensors), or both");
  // The filter is the markers' (orientations are tracked as recorded): without markers it
  // would change nothing, silently.
  if (o.input.empty() && o.filter_hz > 0.0)
    throw std::invalid_argument(
        "--filter-hz low-passes the markers (--input), and there are none: the orientations "
        "are tracked as recorded. Fix: leave out --filter-hz, or give the trial's markers "
        "with --input");
  io::MarkerTrial trial;
  // The warnings said on stderr, in the report too: a batch reads the report, not stderr.
  std::vector<std::string> warnings;
  const auto warn = [&](const std::string& text) {
    std::fprintf(stderr, "fabrik solve: warning: %s\n", safe_lines(text).c_str());
    warnings.push_back(text);
  };
  if (!o.input.empty()) {
    trial = read_trial_or_explain("solve", o.input, o.keep_zeros);
    for (const std::string& w : trial.warnings) warnings.push_back(o.input + ": " + w);
    if (!o.subject.empty()) trial = subject_trial(trial, o.subject);
    const std::size_t implausible = drop_implausible_samples(trial, config.max_abs_coordinate_m);
    if (implausible)
      warn(std::to_string(implausible) + " samples farther than input.max_abs_coordinate_mm (" +
           format_number("%g", config.max_abs_coordinate_m * 1e3) +
           " mm) from the origin are taken as missing, as fabrikd takes them");
    if (o.orientations.empty()) {
      require_shared_markers(config, trial, o.input, "--subject", o.allow_missing_markers,
                             kAllowMissingMarkers);
      require_measured_marker(config, trial, o.input, implausible, "--keep-zeros");
    }
    if (o.filter_hz > 0.0) {
      // A cutoff below one cycle over the trial leaves little but the trial's mean: most often
      // a cutoff written in another unit (0.006 for 6 Hz).
      const double trial_s = static_cast<double>(trial.frames()) / trial.rate_hz;
      if (o.filter_hz * trial_s < 1.0)
        warn("--filter-hz " + format_number("%g", o.filter_hz) +
             " is below one cycle over the trial's " + format_number("%g", trial_s) +
             " s: the markers are flattened to little more than their mean (Pose2Sim's default "
             "is 6 Hz)");
      const std::size_t dropped = drop_left_out_then_filter(config, trial, o.filter_hz);
      if (!o.quiet)
        std::fprintf(stderr,
                     "fabrik solve: markers low-pass filtered at %g Hz (Butterworth, forward and "
                     "backward: no lag), gaps left as gaps, after a first pass (%zu samples "
                     "relabelled as swapped or left out as outliers)\n",
                     o.filter_hz, dropped);
    }
  }
  std::optional<io::OrientationTable> table;
  if (!o.orientations.empty()) {
    table = read_orientations_or_explain("solve", config, o.orientations);
    for (const std::string& w : table->warnings) warnings.push_back(o.orientations + ": " + w);
    if (!o.input.empty())
      for (const std::string& w : time_overlap_warnings(trial, o.input, *table, o.orientations))
        warn(o.orientations + ": " + w);
    if (!o.quiet)
      std::fprintf(stderr, "fabrik solve: %s (%zu rows at %g Hz, %zu sensors)%s\n",
                   safe_lines(o.orientations).c_str(), table->rows(), table->rate_hz,
                   table->sensors.size(),
                   o.input.empty() ? ", no markers: the root stays where the rest posture puts it"
                                   : ", joined on time with the markers");
  }
  if (!o.quiet && !o.input.empty())
    std::fprintf(stderr, "fabrik solve: %s (%zu frames at %g Hz, %zu markers) with %s\n",
                 safe_lines(o.input).c_str(), trial.frames(), trial.rate_hz, trial.markers(),
                 safe_lines(config.file).c_str());
  const TrialSolution s = solve_trial(config, trial, o.quiet ? nullptr : progress_bar,
                                      table ? &*table : nullptr);
  for (const MostlyMissing& m : s.mostly_missing) {
    std::fprintf(stderr,
                 "fabrik solve: warning: tracked marker %s is missing in %zu of %zu frames%s\n",
                 safe_lines(m.marker).c_str(), m.missing_frames, trial.frames(),
                 m.zero_frames > 0
                     ? (" (" + std::to_string(m.zero_frames) + " of them exact (0, 0, 0))").c_str()
                     : "");
  }
  write_trial_file(o.output, s.joints);
  if (!o.markers_output.empty()) {
    write_trial_file(o.markers_output, s.markers);
    if (!filled_csv.empty()) write_filled_csv(filled_csv, s, trial);
  }
  if (!o.model_markers_output.empty()) write_trial_file(o.model_markers_output, s.model_markers);
  // Without coordinates there is no table to write; the run and its summary
  // still stand, and the refusal comes after them.
  const bool angles_refused = !o.angles.empty() && config.tracker.model->coordinates.empty();
  if (!o.angles.empty() && !angles_refused) io::write_opensim_table(o.angles, angles_table(s));
  nlohmann::json summary = solution_summary(s);
  summary["warnings"] = warnings;
  if (!o.report.empty()) {
    std::ofstream out = io::open_output_file(o.report);
    out << summary.dump(2) << '\n';
    io::finish_output_file(out, o.report);
  }
  // The summary beside an output on stdout (--report /dev/stdout | jq) would be mixed in.
  FILE* const summary_to =
      std::any_of(files.begin(), files.end(),
                  [](const tools::NamedFile& f) { return f.output && is_standard_output(f.path); })
          ? stderr
          : stdout;
  const auto& r = summary["residual_mm"];
  // Orientations alone: the marker lines would only count 41 markers "not in the trial".
  const bool markers_given = !o.input.empty();
  if (markers_given)
    std::fprintf(
        summary_to,
        "frames            %zu (%zu without any tracked marker, left out of the residual)\n",
        summary["frames"].get<std::size_t>(), summary["frames_without_markers"].get<std::size_t>());
  else
    std::fprintf(summary_to, "frames            %zu (orientations alone, no marker input)\n",
                 summary["frames"].get<std::size_t>());
  const auto before = summary["frames_before_first_measurement"].get<std::size_t>();
  const auto after = summary["frames_after_last_measurement"].get<std::size_t>();
  if (before + after > 0)
    std::fprintf(
        summary_to,
        "no pose           %s: empty in the TRC and CSV outputs, left out of the .mot\n",
        (before == 0  ? "the last " + std::to_string(after) + " frames, after every measurement"
         : after == 0 ? "the first " + std::to_string(before) + " frames, before any measurement"
                      : "the first " + std::to_string(before) + " and the last " +
                            std::to_string(after) + " frames, outside the measurements")
            .c_str());
  if (markers_given && r["max_marker"].get<std::string>().empty())
    std::fprintf(summary_to, "marker residual   none: no marker measured\n");
  else if (markers_given)
    std::fprintf(
        summary_to,
        "marker residual   RMS %.2f mm (mean over frames; worst frame %.2f mm), max %.2f mm (%s, "
        "frame %lld)\n",
        r["rms_mean"].get<double>(), r["rms_max"].get<double>(), r["max"].get<double>(),
        r["max_marker"].get<std::string>().c_str(), r["max_frame"].get<long long>());
  std::fprintf(summary_to,
               "solve             p50 %.1f us, p99 %.1f us, %.1f iterations on average\n"
               "joint centres     %s\n",
               summary["solve_us"]["p50"].get<double>(), summary["solve_us"]["p99"].get<double>(),
               summary["iterations_mean"].get<double>(), o.output.c_str());
  const auto& out = summary["outliers"];
  const auto& q = summary["quality"];
  // Every verdict, none too (frames without a measured marker), as the report counts them.
  if (markers_given)
    std::fprintf(summary_to,
                 "fit quality       good %d, poor %d, none %d frames (quality thresholds of the "
                 "config)\n"
                 "outliers          %zu marker samples (%.3f %% of measured) in %zu frames, left "
                 "out of their solve\n",
                 q.value("good", 0), q.value("poor", 0), q.value("none", 0),
                 out["samples"].get<std::size_t>(), out["percent_of_measured"].get<double>(),
                 out["frames"].get<std::size_t>());
  std::size_t filled_samples = 0;
  for (const FilledRun& f : s.filled) filled_samples += f.end - f.first;
  if (markers_given)
    std::fprintf(
        summary_to, "gaps filled       %zu samples in %zu runs (both sides)%s%s\n", filled_samples,
        s.filled.size(), filled_csv.empty() ? "" : (": " + filled_csv).c_str(),
        s.solved_on_filled_markers ? "; joint centres and angles solved again on the filled markers"
                                   : "");
  if (markers_given && !s.missing_in_trial.empty())
    std::fprintf(summary_to, "not in the trial   %zu tracked marker%s (%s)\n",
                 s.missing_in_trial.size(), s.missing_in_trial.size() == 1 ? "" : "s",
                 safe_lines(name_list(s.missing_in_trial, 12)).c_str());
  if (summary.contains("orientations")) {
    const auto& so = summary["orientations"];
    std::fprintf(summary_to,
                 "orientations      %zu frames with sensors; sensor error RMS %.2f deg (mean over "
                 "frames), worst frame %.2f deg\n",
                 so["frames_with_sensors"].get<std::size_t>(),
                 so["sensor_error_deg"]["rms_mean"].get<double>(),
                 so["sensor_error_deg"]["rms_max"].get<double>());
    if (!s.sensors_missing_in_table.empty())
      std::fprintf(summary_to,
                   "not in the table   %zu of %zu configured sensors (%s): no orientation for "
                   "their segments\n",
                   s.sensors_missing_in_table.size(), config.tracker.sensors.sensors.size(),
                   safe_lines(name_list(s.sensors_missing_in_table, 12)).c_str());
    if (!s.ignored_in_table.empty())
      std::fprintf(summary_to, "not tracked        %zu table column%s (%s)\n",
                   s.ignored_in_table.size(), s.ignored_in_table.size() == 1 ? "" : "s",
                   safe_lines(name_list(s.ignored_in_table, 12)).c_str());
  }
  if (!s.ignored_in_trial.empty())
    std::fprintf(summary_to, "not tracked        %zu trial label%s (%s)\n",
                 s.ignored_in_trial.size(), s.ignored_in_trial.size() == 1 ? "" : "s",
                 safe_lines(name_list(s.ignored_in_trial, 12)).c_str());
  std::fflush(stdout);  // the summary before the refusal on stderr
  if (angles_refused)
    throw std::runtime_error(config.file + ": --angles: the model has no named coordinates, so " +
                             o.angles + " was not written (the other outputs were). Fix: add "
                             "\"coordinates\" to the model or its template");
}

}  // namespace

void add_solve_command(CLI::App& app) {
  auto o = std::make_shared<SolveOptions>();
  CLI::App* c =
      app.add_subcommand("solve", "Track a recorded trial offline, through the daemon's pipeline");
  c->add_option("--config", o->config, "Daemon config (default: the embedded default)");
  c->add_option("--input", o->input, "Trial, .trc or .c3d (markers)")->check(CLI::ExistingFile);
  c->add_option("--orientations", o->orientations,
                "Orientation sensors, OpenSim quaternion .sto (alone, or joined on time with "
                "--input)")
      ->check(CLI::ExistingFile);
  c->add_option("--output", o->output, "Joint centres, .trc (mm) or .csv")->required();
  c->add_option("--markers", o->markers_output,
                "Also write the tracked markers as measured, gaps filled from both sides, .trc "
                "or .csv (a marker never measured stays empty; and FILE.filled.csv: the filled "
                "samples per marker; /dev/null discards both, a terminal or pipe gets the markers "
                "as TRC, without the list)");
  c->add_option("--model-markers", o->model_markers_output,
                "Also write the model's fitted markers at every frame (what fabrikd publishes "
                "live: a few mm from the measurements, predicted where occluded), .trc or .csv");
  c->add_option("--report", o->report, "Write the summary as JSON");
  c->add_option("--angles", o->angles,
                "Also write the model's coordinates as an OpenSim Coordinates file (.mot)");
  c->add_option("--subject", o->subject,
                "Track only this subject's markers, labelled SUBJECT:MARKER (a Vicon C3D of "
                "several subjects); with a config that lists subjects, also its tracking");
  c->add_option("--filter-hz", o->filter_hz,
                "Low-pass the markers before the solve at this cutoff: a 2nd-order Butterworth "
                "forward and backward (zero lag), per run of samples, gaps left as gaps. "
                "Pose2Sim's default is 6 Hz. 0 (default): as recorded")
      ->check(cli::range(0.0, 1e6));
  c->add_flag("--quiet", o->quiet, "No progress bar");
  c->add_flag(kAllowMissingMarkers, o->allow_missing_markers,
              "Track a trial that has fewer than half of the config's marker names (refused by "
              "default: most often another marker set or spelling)");
  c->add_flag("--keep-zeros", o->keep_zeros,
              "Read exact (0, 0, 0) samples as positions (default: as missing markers)");
  c->callback([o] { tools::run_command("solve", [&] { run(*o); }); });
}

}  // namespace fabrik::apps
