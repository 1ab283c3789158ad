#include "calibrate_command.hpp"

#include <cstdio>
#include <exception>
#include <fstream>
#include <iostream>
#include <memory>

#include "calib/calibrate.hpp"
#include "config/daemon_config.hpp"
#include "read_recording.hpp"
#include "tools/run_command.hpp"

namespace fabrik {

namespace {
struct CalibrateArgs {
  std::string template_path, static_path, output_path;
  bool keep_zeros = false;
  calib::CalibrateOptions options;
};

void run_calibrate(const CalibrateArgs& a) {
  const calib::CalibTemplate tmpl = calib::load_template_file(a.template_path);
  const io::MarkerTrial trial =
      apps::read_trial_or_explain("calibrate", a.static_path, a.keep_zeros);
  const calib::CalibrationResult r = calib::calibrate(tmpl, trial, a.static_path, a.options);
  // The config must load as the daemon will load it, before it is written.
  const std::string text = r.config.dump(2) + "\n";
  load_daemon_config(text, a.output_path);
  std::ofstream out(a.output_path, std::ios::binary);
  if (!out) throw std::runtime_error(a.output_path + ": cannot write the config");
  out << text;
  out.close();
  if (!out) throw std::runtime_error(a.output_path + ": writing the config failed");
  std::cout << calib::calibration_report(r) << "Wrote " << a.output_path << " (model '" << tmpl.name
            << "', " << r.fits.size() << " tracked markers)\n";
}
}  // namespace

void add_calibrate_command(CLI::App& app) {
  auto args = std::make_shared<CalibrateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "calibrate",
      "Build a subject's model from a template and a static trial; write a daemon config");
  cmd->add_option("--template", args->template_path, "Model template (fabrikd-template/1 JSON)")
      ->required();
  cmd->add_option("--static", args->static_path, "Static trial (.trc or .c3d)")->required();
  cmd->add_option("--output", args->output_path, "Daemon config to write (fabrikd-config/1)")
      ->required();
  cmd->add_option("--first-frame", args->options.first_frame,
                  "First frame of the averaging window, as numbered in the file (default: the "
                  "first)");
  cmd->add_option("--frames", args->options.frames,
                  "Frames to average (default: to the end of the trial)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--auto-window", args->options.auto_window,
                  "Average the stillest window of N frames (fewest missing samples, then least "
                  "marker motion) instead of --first-frame/--frames")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--keep-zeros", args->keep_zeros,
                "Read exact (0, 0, 0) samples as positions (default: as missing markers)");
  cmd->callback([args] { tools::run_command("calibrate", [&] { run_calibrate(*args); }); });
}

}  // namespace fabrik
