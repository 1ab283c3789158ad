#include "eval_command.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iostream>
#include <map>
#include <memory>

#include "common/device_path.hpp"
#include "common/safe_text.hpp"
#include "eval/eval.hpp"
#include "io/output_file.hpp"
#include "offline/marker_match.hpp"
#include "read_recording.hpp"
#include "tools/cli_checks.hpp"
#include "tools/distinct_files.hpp"
#include "tools/run_command.hpp"
#include "tools/synth.hpp"

namespace fabrik::apps {

namespace {

struct EvalArgs {
  // The recorded subject (walk, gaps, reduction).
  std::string template_path = "config/templates/gait2354.json";
  std::string static_path = "../shared/data/subject01_static.trc";
  std::string walk_path = "../shared/data/subject01_walk1.trc";
  std::string config_path;  // instead of calibrating (also: synthetic's model)
  std::string json_path;
  std::string csv_path;
  std::string reference_path = "../shared/data/subject01_walk1_ik.mot";
  eval::GapOptions gaps;
  eval::SyntheticOptions synthetic;
  eval::ImuSyntheticOptions imu;
  std::string placement_path = "../shared/data/opensense_placement_orientations.sto";
  std::string imu_walk_path = "../shared/data/opensense_walking_orientations.sto";
  std::string angles_path;  // eval imu: the OpenSense walk's coordinates (.mot)
};

void require_file(const std::string& path, const char* option) {
  if (std::filesystem::is_regular_file(path)) return;
  // The defaults are the project's paths (config/..., ../shared/data/...).
  throw std::runtime_error(path + " not found (relative to " +
                           std::filesystem::current_path().string() + "). Fix: run from the " +
                           "project root (with ../shared/data beside it, for the data), or pass " +
                           option);
}

// The subject's config (calibrated from the static trial unless --config) and its trial.
std::pair<DaemonConfig, io::MarkerTrial> subject(const EvalArgs& a) {
  require_file(a.walk_path, "--walk");
  if (!a.config_path.empty()) {
    require_file(a.config_path, "--config");
    std::pair<DaemonConfig, io::MarkerTrial> s{load_daemon_config_file(a.config_path),
                                               read_trial_or_explain("eval", a.walk_path, false)};
    require_shared_markers(s.first, s.second, a.walk_path);
    return s;
  }
  require_file(a.template_path, "--template");
  require_file(a.static_path, "--static");
  std::fprintf(stderr, "calibrating %s with %s; tracking %s\n", safe_lines(a.static_path).c_str(),
               safe_lines(a.template_path).c_str(), safe_lines(a.walk_path).c_str());
  std::pair<DaemonConfig, io::MarkerTrial> s{eval::calibrate_config(a.template_path, a.static_path),
                                             read_trial_or_explain("eval", a.walk_path, false)};
  require_shared_markers(s.first, s.second, a.walk_path);
  return s;
}

// While an output is stdout (--json /dev/stdout | jq), the text report goes to stderr: mixed
// in, the JSON did not parse (and in a file stdout was redirected to, the report overwrote it).
class ReportToStderrIf {
 public:
  explicit ReportToStderrIf(std::initializer_list<std::string> outputs) {
    for (const std::string& path : outputs)
      if (is_standard_output(path)) {
        std::cout.flush();
        saved_ = std::cout.rdbuf(std::cerr.rdbuf());
        return;
      }
  }
  ~ReportToStderrIf() {
    if (!saved_) return;
    std::cout.flush();
    std::cout.rdbuf(saved_);
  }
  ReportToStderrIf(const ReportToStderrIf&) = delete;
  ReportToStderrIf& operator=(const ReportToStderrIf&) = delete;

 private:
  std::streambuf* saved_ = nullptr;
};

void write_json(const std::string& path, const nlohmann::json& j) {
  if (path.empty()) return;
  std::ofstream out = io::open_output_file(path);
  out << j.dump(2) << '\n';
  io::finish_output_file(out, path);
}

void run(const std::string& which, const EvalArgs& a) {
  // Before the evaluation (minutes on a walk): an output that would replace an input this
  // command reads or the other output, or that cannot be written.
  std::vector<tools::NamedFile> files = {{"--config", a.config_path, false}};
  if (which == "imu") {
    files.insert(files.end(), {{"--template", a.template_path, false},
                               {"--static", a.static_path, false},
                               {"--placement", a.placement_path, false},
                               {"--walk", a.imu_walk_path, false},
                               {"--angles", a.angles_path}});
  } else if (which != "synthetic") {
    files.push_back({"--walk", a.walk_path, false});
    if (a.config_path.empty())
      files.insert(files.end(),
                   {{"--template", a.template_path, false}, {"--static", a.static_path, false}});
    if (which == "angles") files.push_back({"--reference", a.reference_path, false});
  }
  files.insert(files.end(), {{"--json", a.json_path}, {"--csv", a.csv_path}});
  tools::require_usable_outputs(files);
  const ReportToStderrIf report_aside{a.json_path, a.csv_path, a.angles_path};
  if (which == "synthetic") {
    const DaemonConfig config =
        a.config_path.empty() ? default_daemon_config() : load_daemon_config_file(a.config_path);
    const auto rows = eval::eval_synthetic(config, a.synthetic);
    std::cout << "model: " << config.tracker.model->name << " (" << config.file << ")\n"
              << eval::synthetic_table(rows);
    write_json(a.json_path, eval::synthetic_json(rows));
    return;
  }
  if (which == "imu") {
    const DaemonConfig config =
        a.config_path.empty() ? default_daemon_config() : load_daemon_config_file(a.config_path);
    const auto rows = eval::eval_imu_synthetic(config, a.imu);
    std::cout << "model: " << config.tracker.model->name << " (" << config.file << ")\n"
              << eval::imu_synthetic_table(rows, a.imu);
    nlohmann::json j = nlohmann::json::array();
    for (const auto& r : rows)
      j.push_back({{"setup", r.setup}, {"markers", r.markers}, {"sensors", r.sensors},
                   {"joint_angle_rms_deg", r.joint_angle_rms_rad * 180 / 3.141592653589793},
                   {"joint_angle_max_deg", r.joint_angle_max_rad * 180 / 3.141592653589793},
                   {"joint_rms_mm", r.joint_rms_m * 1e3}, {"joint_max_mm", r.joint_max_m * 1e3}});
    nlohmann::json out = {{"synthetic", j}};
    for (const auto& [path, option] : {std::pair{a.template_path, "--template"},
                                       {a.static_path, "--static"},
                                       {a.placement_path, "--placement"},
                                       {a.imu_walk_path, "--walk"}})
      if (!std::filesystem::is_regular_file(path)) {
        std::cout << "\nOpenSense walk skipped: " << path << " not found (" << option << ")\n";
        write_json(a.json_path, out);
        return;
      }
    const eval::OpenSenseRun run = eval::eval_imu_opensense(a.template_path, a.static_path,
                                                            a.placement_path, a.imu_walk_path);
    std::cout << "\n" << eval::gait_table(run.report);
    if (!a.angles_path.empty()) {
      io::write_opensim_table(a.angles_path, angles_table(run.solution));
      std::cout << "coordinates: " << a.angles_path << " (scripts/plot_angles.py --mot)\n";
    }
    const eval::GaitReport& g = run.report;
    nlohmann::json peaks = nlohmann::json::array();
    for (const auto& st : g.strides)
      peaks.push_back({{"side", std::string(1, st.side)}, {"time_s", st.time_s},
                       {"knee_flexion_deg", st.knee_flexion_deg}});
    out["opensense"] = {{"frames", g.frames}, {"frames_tracked", g.frames_tracked},
                        {"knee_peaks", peaks}, {"alternating", g.alternating},
                        {"knee_flexion_min_deg", g.knee_flexion_min_deg},
                        {"hip_flexion_deg", {g.hip_flexion_min_deg, g.hip_flexion_max_deg}},
                        {"max_jump_deg", g.max_jump_deg},
                        {"max_jump_coordinate", g.max_jump_coordinate},
                        {"sensor_error_rms_deg", g.sensor_error_rms_deg}};
    write_json(a.json_path, out);
    return;
  }
  const auto [config, trial] = subject(a);
  if (which == "walk") {
    const eval::WalkReport r = eval::eval_walk(config, trial);
    std::cout << eval::walk_table(r);
    write_json(a.json_path, eval::walk_json(r));
    eval::write_walk_csv(a.csv_path, r);
    std::cout << "per-frame residuals: " << a.csv_path << "\n";
  } else if (which == "gaps") {
    const eval::GapReport r = eval::eval_gaps(config, trial, a.gaps);
    std::cout << eval::gaps_table(r);
    write_json(a.json_path, eval::gaps_json(r));
    eval::write_gaps_csv(a.csv_path, r);
    std::cout << "withheld vs predicted traces: " << a.csv_path << "\n";
  } else if (which == "angles") {
    require_file(a.reference_path, "--reference");
    const io::OpenSimTable reference = io::read_opensim_table(a.reference_path);
    for (const std::string& w : reference.warnings)
      std::fprintf(stderr, "%s: warning: %s\n", safe_lines(a.reference_path).c_str(),
                   safe_lines(w).c_str());
    const eval::AngleReport r = eval::eval_angles(config, trial, reference, a.reference_path);
    std::cout << eval::angles_table(r);
    write_json(a.json_path, eval::angles_json(r));
    eval::write_angles_csv(a.csv_path, r);
    std::cout << "curves: " << a.csv_path << " (scripts/plot_angles.py)\n";
  } else if (which == "reduction") {
    const auto rows = eval::eval_reduction(config, trial, eval::gait2354_drop_sets());
    std::cout << eval::reduction_table(rows);
    write_json(a.json_path, eval::reduction_json(rows));
  }
}

// `fabrik eval markerless` (docs/keypoints.md).
void add_markerless(CLI::App* eval) {
  struct Args {
    eval::MarkerlessOptions o;
    std::string overrides, json_path;
  };
  auto a = std::make_shared<Args>();
  CLI::App* c = eval->add_subcommand(
      "markerless",
      "A markerless trial of our own making: keypoints rendered from synthetic motion with "
      "jitter, dropouts and left/right swaps; calibrated from itself and tracked; joint centres "
      "and angles vs the truth");
  c->add_option("--template", a->o.template_path, "Keypoint template")->capture_default_str();
  c->add_option("--seconds", a->o.seconds, "Duration")
      ->capture_default_str()
      ->check(cli::range(0.5, 3600.0));
  c->add_option("--rate", a->o.rate_hz, "Frame rate (Hz)")
      ->capture_default_str()
      ->check(cli::range(1.0, 10000.0));
  c->add_option("--seed", a->o.seed, "Motion and corruption seed")->capture_default_str();
  c->add_option("--cases", a->o.cases, "Of clean, jitter, dropouts, swaps, all")
      ->capture_default_str();
  KeypointCorruption& k = a->o.corruption;
  c->add_option("--jitter-mm", k.jitter_mm, "Jitter sd per axis (mm)")
      ->capture_default_str()
      ->check(cli::range(0.0, 200.0));
  c->add_option("--dropouts-per-s", k.dropouts_per_s, "Dropout runs per second")
      ->capture_default_str()
      ->check(cli::range(0.0, 1000.0));
  c->add_option("--dropout-frames-max", k.dropout_frames_max, "Each dropout: 2 to N frames")
      ->capture_default_str()
      ->check(cli::range(2, 100000));
  c->add_option("--swaps-per-s", k.swaps_per_s, "Left/right swaps per second")
      ->capture_default_str()
      ->check(cli::range(0.0, 1000.0));
  c->add_option("--swap-frames-max", k.swap_frames_max, "Each swap: 2 to N frames")
      ->capture_default_str()
      ->check(cli::range(2, 100000));
  c->add_option("--limb-swap-share", k.limb_swap_share, "Share of swaps of a whole limb")
      ->capture_default_str()
      ->check(cli::range(0.0, 1.0));
  c->add_option("--config-overrides", a->overrides,
                "JSON (or @FILE) merged into the calibrated config before tracking (RFC 7396 "
                "merge patch), e.g. tracking options a config sets");
  c->add_option("--path", a->o.path,
                "live (frame by frame as recorded) or offline (low-passed at --filter-hz by a "
                "zero-lag Butterworth first)")
      ->check(CLI::IsMember({"live", "offline"}))
      ->capture_default_str();
  c->add_option("--filter-hz", a->o.filter_hz, "offline path: the low-pass cutoff (Hz)")
      ->check(cli::range(0.1, 1e4))
      ->capture_default_str();
  c->add_option("--trial", a->o.trial_path,
                "Instead of generating: a trial written by fabrik synth --keypoints (with its "
                ".joints.trc, .truth.mot and .injected.csv)");
  c->add_option("--json", a->json_path, "Also write the results as JSON");
  c->callback([a] {
    tools::run_command("eval markerless", [&] {
      std::vector<tools::NamedFile> files = {{"--template", a->o.template_path, false}};
      if (!a->o.trial_path.empty()) {  // and what synth wrote beside it, read too
        const std::string stem = tools::sidecar_stem(a->o.trial_path);
        files.insert(files.end(), {{"--trial", a->o.trial_path, false},
                                   {"--trial's FILE.joints.trc", stem + ".joints.trc", false},
                                   {"--trial's FILE.truth.mot", stem + ".truth.mot", false},
                                   {"--trial's FILE.injected.csv", stem + ".injected.csv", false}});
      }
      if (!a->overrides.empty() && a->overrides[0] == '@')
        files.push_back({"--config-overrides", a->overrides.substr(1), false});
      files.push_back({"--json", a->json_path});
      tools::require_usable_outputs(files);
      const ReportToStderrIf report_aside{a->json_path};
      require_file(a->o.template_path, "--template");
      if (!a->o.trial_path.empty()) require_file(a->o.trial_path, "--trial");
      if (!a->overrides.empty()) {
        std::string text = a->overrides;
        if (text[0] == '@') {
          std::ifstream in(text.substr(1));
          if (!in) throw std::runtime_error(text.substr(1) + ": cannot read");
          text.assign(std::istreambuf_iterator<char>(in), {});
        }
        a->o.config_overrides = nlohmann::json::parse(text);
      }
      const auto rows = eval::eval_markerless(a->o);
      std::cout << eval::markerless_table(rows, a->o);
      write_json(a->json_path, eval::markerless_json(rows));
    });
  });
}

}  // namespace

void add_eval_command(CLI::App& app) {
  CLI::App* eval = app.add_subcommand("eval", "Accuracy evaluations on real and synthetic data");
  eval->require_subcommand(1);
  const auto add = [&](const std::string& name, const std::string& help, bool recorded,
                       const std::string& csv_default) {
    auto a = std::make_shared<EvalArgs>();
    CLI::App* c = eval->add_subcommand(name, help);
    if (recorded) {
      c->add_option("--template", a->template_path, "Model template")->capture_default_str();
      c->add_option("--static", a->static_path, "Static trial to calibrate from")
          ->capture_default_str();
      c->add_option("--walk", a->walk_path, "Trial to track")->capture_default_str();
      c->add_option("--config", a->config_path,
                    "Daemon config to use instead of calibrating --template on --static");
    } else {
      c->add_option("--config", a->config_path, "Daemon config (default: the embedded default)");
    }
    if (!csv_default.empty()) {
      a->csv_path = csv_default;
      c->add_option("--csv", a->csv_path, "CSV for scripts/plot_eval.py or plot_angles.py")
          ->capture_default_str();
    }
    c->add_option("--json", a->json_path, "Also write the results as JSON");
    c->callback([name, a] { tools::run_command("eval " + name, [&] { run(name, *a); }); });
    return std::make_pair(c, a);
  };
  add("walk", "Marker residuals of a calibrated subject on a recorded trial", true,
      "eval_walk.csv");
  auto [gaps, ga] =
      add("gaps",
          "Withhold each marker in turn for 0.1-2 s windows; compare the live and offline fill",
          true, "eval_gaps.csv");
  gaps->add_option("--windows", ga->gaps.windows_s, "Gap lengths (s)")->capture_default_str();
  gaps->add_option("--stride", ga->gaps.stride_s, "Between window starts (s)")
      ->capture_default_str()
      ->check(cli::above_zero());
  gaps->add_option("--modes", ga->gaps.modes, "live, offline or both")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, eval::GapMode>{{"live", eval::GapMode::live},
                                               {"offline", eval::GapMode::offline}}));
  gaps->add_option("--markers", ga->gaps.markers, "Markers to withhold (default: all tracked)");
  auto [angles, aa] = add("angles",
                          "Joint angles and translations vs a reference .mot (e.g. OpenSim's IK)",
                          true, "eval_angles.csv");
  angles->add_option("--reference", aa->reference_path, "Reference Coordinates table (.mot/.sto)")
      ->capture_default_str();
  add("reduction", "Joint centres with marker subsets left out, vs the full set", true, "");
  auto [synth, sa] = add(
      "synthetic", "Joint centres vs the truth on synthetic motion with marker noise", false, "");
  synth->add_option("--noise-mm", sa->synthetic.noise_mm, "Noise levels, per axis (mm)")
      ->capture_default_str();
  synth->add_option("--seconds", sa->synthetic.seconds, "Duration per noise level")
      ->capture_default_str()
      ->check(cli::above_zero());
  synth->add_option("--seed", sa->synthetic.seed, "Motion and noise seed")->capture_default_str();
  auto ia = std::make_shared<EvalArgs>();
  ia->template_path = "config/templates/opensense_gait2354.json";
  CLI::App* imu = eval->add_subcommand(
      "imu", "Orientation sensors: synthetic truth (markers, IMUs, pelvis markers + IMUs) and "
             "the OpenSense walk from its IMUs alone");
  imu->add_option("--config", ia->config_path,
                  "Daemon config for the synthetic part (default: the embedded default)");
  imu->add_option("--noise-deg", ia->imu.sensor_noise_deg, "IMU noise per axis (deg)")
      ->capture_default_str();
  imu->add_option("--drift-deg-per-s", ia->imu.drift_deg_per_s, "IMU heading drift rate bound")
      ->capture_default_str();
  imu->add_option("--seconds", ia->imu.seconds, "Synthetic duration")
      ->capture_default_str()
      ->check(cli::above_zero());
  imu->add_option("--seed", ia->imu.seed, "Motion and noise seed")->capture_default_str();
  imu->add_option("--template", ia->template_path, "Template with sensors")->capture_default_str();
  imu->add_option("--static", ia->static_path, "Static marker trial (the body's geometry)")
      ->capture_default_str();
  imu->add_option("--placement", ia->placement_path, "Calibration pose orientations (.sto)")
      ->capture_default_str();
  imu->add_option("--walk", ia->imu_walk_path, "Walk orientations (.sto)")->capture_default_str();
  imu->add_option("--angles", ia->angles_path, "Write the walk's coordinates (.mot)");
  imu->add_option("--json", ia->json_path, "Also write the results as JSON");
  imu->callback([ia] { tools::run_command("eval imu", [&] { run("imu", *ia); }); });
  add_markerless(eval);
}

}  // namespace fabrik::apps
