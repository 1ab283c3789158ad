#include "calibrate_command.hpp"

#include <cstdio>
#include <exception>
#include <fstream>
#include <iostream>
#include <limits>
#include <memory>

#include "calib/calibrate.hpp"
#include "calib/keypoint_calibration.hpp"
#include "calib/sensor_calibration.hpp"
#include "config/daemon_config.hpp"
#include "config/json_reader.hpp"
#include "config/lab_axes_json.hpp"
#include "config/model_loader.hpp"
#include "io/orientation_table.hpp"
#include "io/output_file.hpp"
#include "read_recording.hpp"
#include "tools/cli_checks.hpp"
#include "tools/distinct_files.hpp"
#include "tools/run_command.hpp"

namespace fabrik {

namespace {
struct CalibrateArgs {
  std::string template_path, static_path, output_path, orientations_path, config_path;
  std::string trial_path, lengths_json_path;  // keypoint templates: any movement, no static
  std::string lab_up, lab_forward;
  bool keep_zeros = false;
  bool nominal = false;  // keypoint templates: the nominal lengths, no trial
  calib::CalibrateOptions options;
};

// The config must load as the daemon will load it, before it is written.
DaemonConfig write_config(const nlohmann::ordered_json& config, const std::string& path) {
  const std::string text = config.dump(2) + "\n";
  DaemonConfig loaded = load_daemon_config(text, path);
  std::ofstream out = io::open_output_file(path);
  out << text;
  io::finish_output_file(out, path);
  return loaded;
}

io::OrientationTable read_orientations(const std::string& path) {
  io::OrientationTable table = io::read_orientation_table(path);
  apps::print_warnings("calibrate", path, table.warnings);
  return table;
}

// Sensors of the template (or of the config) calibrated from the calibration pose.
std::string calibrated_sensors(const SensorSection& spec, const Model& model,
                               const std::string& table_path, nlohmann::ordered_json& config) {
  return calib::calibrate_sensors_into(spec, model, read_orientations(table_path), table_path,
                                       config);
}

void run_calibrate(const CalibrateArgs& a) {
  const std::vector<tools::NamedFile> files = {
      {"--template", a.template_path, false},
      {"--static", a.static_path, false},
      {"--trial", a.trial_path, false},
      {"--static-orientations", a.orientations_path, false},
      // --config may be --output: its sensors recalibrated in place
      // (read whole before the write).
      {"--output", a.output_path},
      {"--lengths-json", a.lengths_json_path}};
  tools::require_usable_outputs(files);
  if (!a.lengths_json_path.empty() && a.trial_path.empty() && !a.nominal)
    throw std::invalid_argument(
        "--lengths-json goes with --trial (the lengths measured from a "
        "keypoint trial) or --nominal; with --static it has nothing to "
        "write");
  if (!a.config_path.empty()) {
    // Sensors only: a subject's config, a new calibration pose (a new session).
    if (!a.template_path.empty() || !a.static_path.empty() || a.orientations_path.empty())
      throw std::runtime_error("--config recalibrates a config's sensors: give it with "
                               "--static-orientations only (no --template, no --static)");
    const DaemonConfig config = load_daemon_config_file(a.config_path);
    if (config.sensors.entries.empty())
      throw std::runtime_error(a.config_path + ": has no \"sensors\" to calibrate. Fix: "
                               "calibrate from a template with \"sensors\"");
    std::string text;
    if (auto p = read_text_file(a.config_path, text)) throw std::runtime_error(p->problem);
    nlohmann::ordered_json json = nlohmann::ordered_json::parse(text);
    const std::string report =
        calibrated_sensors(config.sensors, *config.tracker.model, a.orientations_path, json);
    write_config(json, a.output_path);
    std::cout << report << "Wrote " << a.output_path << " (the sensors of " << a.config_path
              << " recalibrated)\n";
    return;
  }
  if (a.template_path.empty() ||
      int(!a.static_path.empty()) + int(!a.trial_path.empty()) + int(a.nominal) != 1)
    throw std::runtime_error(
        "give --template and one of --static (a marker template), "
        "--trial or --nominal (a keypoint template); or --config with "
        "--static-orientations to recalibrate a config's sensors");
  const calib::CalibTemplate tmpl = calib::load_template_file(a.template_path);
  const bool keypoints = tmpl.kind == calib::TemplateKind::keypoints;
  if (keypoints == !a.static_path.empty())
    throw std::runtime_error(
        keypoints ? calib::keypoint_template_not_static(a.template_path) +
                        ". Fix: give --trial or --nominal instead of --static"
                  : a.template_path +
                        " is a marker template: it calibrates from a static trial. Fix: give "
                        "--static instead of " +
                        (a.nominal ? "--nominal" : "--trial"));
  calib::CalibrateOptions options = a.options;
  if (!a.lab_up.empty()) {
    const nlohmann::json axes = a.lab_forward.empty()
                                    ? nlohmann::json{{"up", a.lab_up}}
                                    : nlohmann::json{{"up", a.lab_up}, {"forward", a.lab_forward}};
    options.lab_axes = read_lab_axes(JsonReader(axes, "--lab-up/--lab-forward"));
  } else if (!a.lab_forward.empty()) {
    throw std::runtime_error("--lab-forward needs --lab-up: give both");
  }
  if (!a.orientations_path.empty() && tmpl.sensors.entries.empty())
    throw std::runtime_error(a.template_path + " lists no orientation sensors, so --static-"
                             "orientations has nothing to calibrate. Fix: add \"sensors\" to "
                             "the template");
  if (keypoints) {
    if (options.auto_window > 0)
      throw std::runtime_error("--auto-window picks a still window; a keypoint template measures "
                               "lengths over movement. Fix: --first-frame/--frames, or neither");
    calib::KeypointCalibration k;
    if (a.nominal) {
      k = calib::nominal_keypoint_model(tmpl, options.lab_axes);
    } else {
      const io::MarkerTrial trial =
          apps::read_trial_or_explain("calibrate", a.trial_path, a.keep_zeros);
      calib::KeypointCalibrateOptions ko;
      ko.first_frame = options.first_frame;
      ko.frames = options.frames;
      ko.lab_axes = options.lab_axes;
      k = calib::calibrate_keypoints(tmpl, trial, a.trial_path, ko);
    }
    const DaemonConfig written = write_config(k.result.config, a.output_path);
    if (!a.lengths_json_path.empty()) {
      std::ofstream out = io::open_output_file(a.lengths_json_path);
      out << calib::keypoint_lengths_json(k).dump(2) << "\n";
      io::finish_output_file(out, a.lengths_json_path);
    }
    std::cout << calib::keypoint_length_report(k) << calib::calibration_report(k.result)
              << "Wrote " << a.output_path << " (model '" << tmpl.name << "', "
              << written.tracker.markers.size() << " tracked keypoints)\n";
    return;
  }
  const io::MarkerTrial trial =
      apps::read_trial_or_explain("calibrate", a.static_path, a.keep_zeros);
  calib::CalibrationResult r = calib::calibrate(tmpl, trial, a.static_path, options);
  std::string sensors;
  if (!a.orientations_path.empty()) {
    const Model model = load_model(nlohmann::json::parse(r.model.dump()), "<calibrated model>");
    // The template's sensors' world is given in its lab axes (OpenSim's y up without them);
    // the subject's may be another's (a z-up lab found from the static).
    LabAxes template_lab;
    if (tmpl.lab_axes) {
      template_lab.up_lab = tmpl.lab_axes->up_lab;
      template_lab.forward_lab = tmpl.lab_axes->forward_lab.value_or(
          default_forward_lab(tmpl.lab_axes->up_lab).value_or(model.lab_axes.forward_lab));
    }
    SensorSection spec = tmpl.sensors;
    spec.world = calib::sensor_world_in_lab(spec.world, template_lab, model.lab_axes);
    sensors = calibrated_sensors(spec, model, a.orientations_path, r.config);
  } else if (!tmpl.sensors.entries.empty()) {
    sensors = "\nnote: " + calib::sensors_left_out(tmpl.sensors.entries.size()) +
              ": calibrate them with --static-orientations\n";
  }
  const DaemonConfig written = write_config(r.config, a.output_path);
  std::cout << calib::calibration_report(r) << sensors << "Wrote " << a.output_path
            << " (model '" << tmpl.name << "', " << r.fits.size() << " tracked markers, "
            << written.tracker.sensors.sensors.size() << " orientation sensors)\n";
}
}  // namespace

void add_calibrate_command(CLI::App& app) {
  auto args = std::make_shared<CalibrateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "calibrate",
      "Build a subject's model from a template and a static trial (or, for a keypoint "
      "template, any movement: --trial); write a daemon config");
  cmd->add_option("--template", args->template_path, "Model template (fabrikd-template/1 JSON)");
  cmd->add_option("--static", args->static_path, "Static trial (.trc or .c3d)");
  cmd->add_option("--trial", args->trial_path,
                  "Keypoint templates (\"kind\": \"keypoints\"): any movement trial of the "
                  "keypoints (.trc or .c3d, m or mm); segment lengths are measured from it, no "
                  "static trial (docs/keypoints.md)");
  cmd->add_flag("--nominal", args->nominal,
                "Keypoint templates, instead of --trial: the template at its nominal lengths "
                "(the truth model of `fabrik synth --keypoints`)");
  cmd->add_option("--lengths-json", args->lengths_json_path,
                  "With --trial (or --nominal): also write each measured length and its spread "
                  "as JSON");
  cmd->add_option("--static-orientations", args->orientations_path,
                  "Orientation sensors recorded in the model's rest posture (OpenSim quaternion "
                  ".sto): calibrates the template's sensors");
  cmd->add_option("--config", args->config_path,
                  "Instead of --template and --static: recalibrate this config's sensors from "
                  "--static-orientations");
  cmd->add_option("--output", args->output_path, "Daemon config to write (fabrikd-config/1)")
      ->required();
  cmd->add_option("--first-frame", args->options.first_frame,
                  "First frame of the averaging window, as numbered in the file (default: the "
                  "first)")
      ->check(cli::range(0LL, std::numeric_limits<long long>::max()));
  cmd->add_option("--frames", args->options.frames,
                  "Frames to average (default: to the end of the trial)")
      ->check(cli::above_zero());
  cmd->add_option("--auto-window", args->options.auto_window,
                  "Average the stillest window of N frames (fewest missing samples, then least "
                  "marker motion) instead of --first-frame/--frames")
      ->check(cli::above_zero());
  cmd->add_option("--lab-up", args->lab_up,
                  "The lab's up axis, e.g. +z (Vicon Nexus, QTM) or +y (OpenSim); overrides the "
                  "template's \"lab_axes\". Default: detected from the static trial");
  cmd->add_option("--lab-forward", args->lab_forward,
                  "With --lab-up: the lab's forward axis, e.g. +x (default: +x while it is "
                  "horizontal, else detected)");
  cmd->add_flag("--keep-zeros", args->keep_zeros,
                "Read exact (0, 0, 0) samples as positions (default: as missing markers)");
  cmd->callback([args] { tools::run_command("calibrate", [&] { run_calibrate(*args); }); });
}

}  // namespace fabrik
