// `fabrik bench fullbody`, the figure users get: a daemon config as `fabrik calibrate` writes
// it (a shipped template calibrated on a static trial, its joint ranges and subtree carry on),
// tracked through the Tracker as fabrikd and `fabrik solve` track, on synthetic motion of the
// calibrated model and on recorded trials replayed at their own speed and faster (every k-th
// frame: bigger steps between frames, as in running). Each source is tracked with the config's
// solver options and with the subtree carry toggled (off when the config carries, calibrate's
// 0.5 when it does not), the two trackers interleaved frame by frame (in alternating order) so
// both see the same frames and the same machine load: their ratios are the carry's cost.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <functional>

#include "bench.hpp"
#include "calib/calibrate.hpp"
#include "config/daemon_config.hpp"
#include "config/json_reader.hpp"
#include "config/resources.hpp"
#include "generic_static.hpp"
#include "io/marker_trial.hpp"
#include "stats.hpp"
#include "synth/synthetic_motion.hpp"
#include "tracking/tracker.hpp"

namespace fabrik::embedded {
std::string_view gait2354_template();
}

namespace fabrik::bench {

using nlohmann::json;

namespace {

constexpr const char* kShippedTemplate = "config/templates/gait2354.json";
// The carry compared with when a config has none: what `fabrik calibrate` writes for a
// template with joint limits (calibrate.cpp).
constexpr double kCalibrateCarry = 0.5;

// Per frame the measured markers (metres) and their visibility, in the config's marker order.
struct FrameSource {
  std::string name;
  double rate_hz = 100.0;
  int frames = 0;
  std::function<void(int, std::vector<Eigen::Vector3d>&, std::vector<std::uint8_t>&)> frame;
  // Synthetic sources: the true joint centres of frame f (empty function otherwise).
  std::function<void(int, std::vector<Eigen::Vector3d>&)> truth_joints;
};

struct Figures {
  std::vector<double> solve_us, track_cpu_us, iterations, jumps, rms_mm, joint_err_mm;
  double max_mm = 0.0, cold_us = 0.0;
  int converged = 0, stalled = 0, max_iterations = 0;
};

double thread_cpu_us() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e6 + static_cast<double>(t.tv_nsec) * 1e-3;
}

json figures_json(const Figures& f) {
  json j = {
      {"solve_us",
       {{"median", quantile(f.solve_us, 0.5)},
        {"p99", quantile(f.solve_us, 0.99)},
        {"max", quantile(f.solve_us, 1.0)}}},
      // This thread's processor time in the whole track() call: what a busy machine's
      // other processes do not add (wall-time outliers there are preemptions).
      {"track_cpu_us",
       {{"median", quantile(f.track_cpu_us, 0.5)}, {"p99", quantile(f.track_cpu_us, 0.99)}}},
      {"cold_frame_us", f.cold_us},
      {"iterations_mean", mean(f.iterations)},
      {"iterations_p99", quantile(f.iterations, 0.99)},
      {"jumps_mean", mean(f.jumps)},
      {"frames", f.solve_us.size()},
      {"status",
       {{"converged", f.converged}, {"stalled", f.stalled}, {"max_iterations", f.max_iterations}}},
      {"marker_residual_mm", {{"rms_mean", mean(f.rms_mm)}, {"max", f.max_mm}}}};
  if (!f.joint_err_mm.empty())
    j["joint_centre_error_mm"] = {{"rms_mean", mean(f.joint_err_mm)},
                                  {"p99", quantile(f.joint_err_mm, 0.99)}};
  return j;
}

// The carry's cost: ratios of the tracker with the carry to the one without, from one
// interleaved run (the same frames under the same load).
json carry_cost(const Figures& on, const Figures& off, double carry) {
  auto ratio = [](double a, double b) { return b > 0.0 ? a / b : 0.0; };
  return {{"subtree_carry", carry},
          {"median_ratio", ratio(quantile(on.solve_us, 0.5), quantile(off.solve_us, 0.5))},
          {"p99_ratio", ratio(quantile(on.solve_us, 0.99), quantile(off.solve_us, 0.99))},
          {"cpu_median_ratio",
           ratio(quantile(on.track_cpu_us, 0.5), quantile(off.track_cpu_us, 0.5))},
          // Preemptions set the wall-time p99 on a busy machine; the cpu time's is steadier.
          {"cpu_p99_ratio",
           ratio(quantile(on.track_cpu_us, 0.99), quantile(off.track_cpu_us, 0.99))},
          {"iterations_ratio", ratio(mean(on.iterations), mean(off.iterations))}};
}

// Tracks `source` with one Tracker per setup, interleaved frame by frame. The first frame is
// cold (cold_start.hpp) and reported apart.
std::vector<Figures> track_interleaved(const std::vector<TrackerSetup>& setups,
                                       const FrameSource& source) {
  std::vector<std::unique_ptr<Tracker>> trackers;
  for (const TrackerSetup& s : setups) trackers.push_back(std::make_unique<Tracker>(s));
  std::vector<Figures> out(setups.size());
  const std::size_t n = setups.front().markers.size();
  std::vector<Eigen::Vector3d> measured(n), truth;
  std::vector<std::uint8_t> visible(n);
  std::vector<std::size_t> order(setups.size());
  for (int f = 0; f < source.frames; ++f) {
    source.frame(f, measured, visible);
    if (source.truth_joints) source.truth_joints(f, truth);
    for (std::size_t k = 0; k < order.size(); ++k)
      order[k] = f % 2 ? order.size() - 1 - k : k;  // alternate who goes first
    for (std::size_t k : order) {
      const double cpu0_us = thread_cpu_us();
      const TrackResult& r = trackers[k]->track(f / source.rate_hz, measured, visible);
      const double cpu_us = thread_cpu_us() - cpu0_us;
      Figures& fig = out[k];
      if (f == 0) {
        fig.cold_us = r.solve_us;
        continue;
      }
      fig.solve_us.push_back(r.solve_us);
      fig.track_cpu_us.push_back(cpu_us);
      fig.iterations.push_back(r.solve.iterations);
      fig.jumps.push_back(r.solve.jumps);
      fig.converged += r.solve.status == SolveStatus::converged;
      fig.stalled += r.solve.status == SolveStatus::stalled;
      fig.max_iterations += r.solve.status == SolveStatus::max_iterations;
      fig.rms_mm.push_back(r.residual_rms_m * 1e3);
      fig.max_mm = std::max(fig.max_mm, r.residual_max_m * 1e3);
      if (!truth.empty()) {
        double sq = 0.0;
        for (std::size_t j = 0; j < truth.size(); ++j)
          sq += (r.joints_world_m[j] - truth[j]).squaredNorm();
        fig.joint_err_mm.push_back(std::sqrt(sq / static_cast<double>(truth.size())) * 1e3);
      }
    }
  }
  return out;
}

// Smooth synthetic motion of the config's model (within its ranges), `speed` times the
// default gait-like frequency, with marker noise.
FrameSource synthetic_source(const DaemonConfig& config, const FullbodyOptions& options,
                             double speed) {
  const Model& m = *config.tracker.model;
  MotionSettings ms;
  ms.seed = options.seed;
  ms.frequency_hz *= speed;
  auto motion = std::make_shared<SyntheticMotion>(m, ms);
  auto truth = std::make_shared<Posture>(Posture::rest(m));
  auto points = std::make_shared<std::vector<int>>();
  for (const MarkerTarget& t : config.tracker.markers) points->push_back(t.point);
  FrameSource s;
  char name[96];
  std::snprintf(name, sizeof name, "synthetic motion, %.1f Hz cycle, %g mm noise", ms.frequency_hz,
                options.noise_mm);
  s.name = name;
  s.rate_hz = options.rate_hz;
  s.frames = options.frames;
  const double noise_m = options.noise_mm * 1e-3;
  const double rate_hz = options.rate_hz;
  s.frame = [=, &m](int f, std::vector<Eigen::Vector3d>& measured,
                    std::vector<std::uint8_t>& visible) {
    motion->posture_at(f / rate_hz, *truth);
    motion->sample(*truth, *points, noise_m, measured);
    std::fill(visible.begin(), visible.end(), std::uint8_t{1});
  };
  s.truth_joints = [=, &m](int, std::vector<Eigen::Vector3d>& joints) {
    joints.resize(m.joints.size());
    for (std::size_t j = 0; j < m.joints.size(); ++j)
      joints[j] = truth->point_world_m(m, m.joints[j].point);
  };
  return s;
}

// A recorded trial played forward and back (so it never jumps), every `step`-th frame, for
// `frames` frames.
FrameSource replay_source(const DaemonConfig& config, std::shared_ptr<const io::MarkerTrial> trial,
                          const std::string& file, int step, int frames) {
  auto column = std::make_shared<std::vector<int>>();
  for (const MarkerTarget& t : config.tracker.markers) column->push_back(trial->find(t.marker));
  const int sweep = static_cast<int>((trial->frames() - 1) / step);  // steps per direction
  FrameSource s;
  s.name = std::filesystem::path(file).filename().string() +
           (step == 1 ? std::string(", as recorded")
                      : ", 1 frame in " + std::to_string(step) + " (" + std::to_string(step) +
                            "x speed)");
  s.rate_hz = trial->rate_hz / step;
  s.frames = frames;
  s.frame = [=](int f, std::vector<Eigen::Vector3d>& measured, std::vector<std::uint8_t>& visible) {
    const int k = sweep > 0 ? f % (2 * sweep) : 0;
    const std::size_t row = static_cast<std::size_t>((k <= sweep ? k : 2 * sweep - k) * step);
    for (std::size_t i = 0; i < column->size(); ++i) {
      const int c = (*column)[i];
      measured[i] = c >= 0 ? trial->at(row, c) : Eigen::Vector3d::Constant(NAN);
      visible[i] = measured[i].allFinite() ? 1 : 0;
    }
  };
  return s;
}

// How many of the config's markers the trial has.
int markers_found(const DaemonConfig& config, const io::MarkerTrial& trial) {
  int found = 0;
  for (const MarkerTarget& t : config.tracker.markers) found += trial.find(t.marker) >= 0;
  return found;
}

// The config to measure: the given file, or the shipped template calibrated on the static
// trial (a generated one when the file is absent).
DaemonConfig bench_config(const FullbodyOptions& options, std::string& origin) {
  if (!options.config.empty()) {
    origin = options.config;
    return load_daemon_config_file(options.config);
  }
  const bool on_disk = std::filesystem::exists(options.template_path);
  const std::string text = on_disk || options.template_path != kShippedTemplate
                               ? read_config_text(options.template_path)
                               : std::string(embedded::gait2354_template());
  const calib::CalibTemplate tmpl =
      calib::load_template(JsonReader::parse(text, options.template_path), options.template_path);
  io::MarkerTrial trial;
  std::string static_name = options.static_trial;
  if (!options.static_trial.empty() && std::filesystem::exists(options.static_trial)) {
    trial = io::read_trial(options.static_trial);
  } else {
    trial = generic_gait2354_static();
    static_name = "a generated static trial (" +
                  (options.static_trial.empty() ? std::string("none given")
                                                : options.static_trial + " not found") +
                  ")";
  }
  const calib::CalibrationResult r = calib::calibrate(tmpl, trial, static_name);
  origin = options.template_path + " calibrated on " + static_name;
  return load_daemon_config(r.config.dump(), "<" + origin + ">");
}

}  // namespace

json run_calibrated(const FullbodyOptions& options) {
  std::string origin;
  const DaemonConfig config = bench_config(options, origin);
  // The config as it is, and the same with the carry toggled: every config gets the carry's
  // cost, including one that does not carry (the embedded default).
  const double carry = config.tracker.solver.subtree_carry;
  std::vector<TrackerSetup> setups = {config.tracker, config.tracker};
  setups[1].solver.subtree_carry = carry > 0.0 ? 0.0 : kCalibrateCarry;
  // Off is FABRIK's own rule throughout: no fallback carry either.
  if (carry > 0.0) setups[1].solver.fallback_carry = 0.0;
  const std::size_t on = carry > 0.0 ? 0 : 1;  // the setup that carries
  std::vector<FrameSource> sources;
  for (double speed : options.speeds) sources.push_back(synthetic_source(config, options, speed));
  json skipped = json::array();
  for (const std::string& file : options.trials) {
    if (!std::filesystem::exists(file)) continue;
    auto trial = std::make_shared<const io::MarkerTrial>(io::read_trial(file));
    const int found = markers_found(config, *trial);
    const int wanted = static_cast<int>(config.tracker.markers.size());
    if (2 * found < wanted) {  // another model's trial: its timings would mean nothing
      skipped.push_back({{"trial", file}, {"markers_found", found}, {"markers", wanted}});
      continue;
    }
    for (int step : options.steps)
      sources.push_back(replay_source(config, trial, file, step, options.frames));
  }
  json runs = json::array();
  for (const FrameSource& s : sources) {
    const std::vector<Figures> f = track_interleaved(setups, s);
    json run = {{"source", s.name}, {"rate_hz", s.rate_hz}, {"as_configured", figures_json(f[0])}};
    run[carry > 0.0 ? "without_carry" : "with_carry"] = figures_json(f[1]);
    run["carry"] = carry_cost(f[on], f[1 - on], setups[on].solver.subtree_carry);
    runs.push_back(run);
  }
  const Model& m = *config.tracker.model;
  json segment_names = json::array();
  for (const Segment& seg : m.segments) segment_names.push_back(seg.name);
  return {{"config", origin},
          {"model",
           {{"name", m.name},
            {"segments", m.segments.size()},
            {"segment_names", segment_names},
            {"markers", config.tracker.markers.size()},
            {"joint_limits", m.has_joint_limits()}}},
          {"skipped_trials", skipped},
          {"solver",
           {{"subtree_carry", carry},
            {"max_iterations", config.tracker.solver.max_iterations},
            {"tolerance_mm", config.tracker.solver.tolerance_m * 1e3},
            {"stall_tolerance_mm", config.tracker.solver.stall_tolerance_m * 1e3}}},
          {"runs", runs}};
}

std::string calibrated_table(const json& r) {
  auto line = [](const char* title, const json& t) {
    char joints[64] = "";
    if (t.contains("joint_centre_error_mm"))
      std::snprintf(joints, sizeof joints, ", joints %.2f mm from the truth",
                    t["joint_centre_error_mm"]["rms_mean"].get<double>());
    char buf[640];
    const json& st = t["status"];
    std::snprintf(buf, sizeof buf,
                  "  %-14s solve median %6.1f us, p99 %6.1f, max %7.1f (track cpu %5.1f, p99 "
                  "%5.1f)  iterations %5.2f (p99 %2.0f, jumps %.2f)  converged/stalled/cap "
                  "%d/%d/%d  residual %.2f mm (max %.1f)%s\n",
                  title, t["solve_us"]["median"].get<double>(), t["solve_us"]["p99"].get<double>(),
                  t["solve_us"]["max"].get<double>(), t["track_cpu_us"]["median"].get<double>(),
                  t["track_cpu_us"]["p99"].get<double>(), t["iterations_mean"].get<double>(),
                  t["iterations_p99"].get<double>(), t["jumps_mean"].get<double>(),
                  st["converged"].get<int>(), st["stalled"].get<int>(),
                  st["max_iterations"].get<int>(),
                  t["marker_residual_mm"]["rms_mean"].get<double>(),
                  t["marker_residual_mm"]["max"].get<double>(), joints);
    return std::string(buf);
  };
  char head[768];
  std::snprintf(head, sizeof head,
                "As users run it: %s\n  model %s, %d segments, %d markers; subtree carry %g, "
                "max %d iterations, stall %g mm; first (cold) frame left out\n",
                r["config"].get<std::string>().c_str(),
                r["model"]["name"].get<std::string>().c_str(), r["model"]["segments"].get<int>(),
                r["model"]["markers"].get<int>(), r["solver"]["subtree_carry"].get<double>(),
                r["solver"]["max_iterations"].get<int>(),
                r["solver"]["stall_tolerance_mm"].get<double>());
  std::string out = head;
  for (const json& s : r["skipped_trials"]) {
    char buf[512];
    std::snprintf(buf, sizeof buf, "skipped %s: it has %d of the config's %d markers\n",
                  s["trial"].get<std::string>().c_str(), s["markers_found"].get<int>(),
                  s["markers"].get<int>());
    out += buf;
  }
  for (const json& run : r["runs"]) {
    out += run["source"].get<std::string>() + ", " +
           std::to_string(static_cast<int>(run["as_configured"]["frames"].get<int>())) +
           " frames\n";
    out += line("as configured", run["as_configured"]);
    const json& c = run["carry"];
    char title[32];
    std::snprintf(title, sizeof title, "carry %g", c["subtree_carry"].get<double>());
    out += run.contains("without_carry") ? line("carry off", run["without_carry"])
                                         : line(title, run["with_carry"]);
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "  the carry's cost (%g against 0, same frames): median %.2fx, p99 %.2fx, "
                  "track cpu median %.2fx, p99 %.2fx, iterations %.2fx\n",
                  c["subtree_carry"].get<double>(), c["median_ratio"].get<double>(),
                  c["p99_ratio"].get<double>(), c["cpu_median_ratio"].get<double>(),
                  c["cpu_p99_ratio"].get<double>(), c["iterations_ratio"].get<double>());
    out += buf;
  }
  double lo = 0.0, hi = 0.0;
  for (const json& run : r["runs"]) {
    const double x = run["carry"]["median_ratio"].get<double>();
    lo = lo > 0.0 ? std::min(lo, x) : x;
    hi = std::max(hi, x);
  }
  if (r["runs"].size() > 1) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "The carry's cost over the %zu sources: median %.2f-%.2fx\n",
                  r["runs"].size(), lo, hi);
    out += buf;
  }
  return out;
}

}  // namespace fabrik::bench
