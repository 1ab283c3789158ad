// `fabrik bench fullbody`: the built-in full-body model tracking smooth
// synthetic motion with marker noise, warm-started frame to frame.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>

#include "bench.hpp"
#include "config/json_reader.hpp"
#include "config/model_loader.hpp"
#include "config/resources.hpp"
#include "solver/fabrik_solver.hpp"
#include "solver/model_builder.hpp"
#include "stats.hpp"
#include "synth/synthetic_motion.hpp"

namespace fabrik::bench {

using nlohmann::json;

namespace {

struct Track {
  std::vector<double> times_us, rms_mm, iterations, passes, joint_err_mm, joint_limit_deg;
  double max_residual_mm = 0.0;
};

// Every marker at level 0, or, as the embedded daemon config does, the
// pelvis markers (the model's root segment) one level stronger.
std::vector<Target> bench_targets(const Model& m, bool pelvis_stronger) {
  std::vector<Target> targets;
  for (int p : m.marker_points()) {
    const bool pelvis = m.points[p].segment == 0;
    targets.push_back({p, pelvis_stronger && pelvis ? 1 : 0, 1.0});
  }
  return targets;
}

// Tracks the synthetic motion of `truth_model` with a solver on `model`
// (the same geometry, with or without joint limits), warm-started.
Track track(const std::shared_ptr<const Model>& model, const Model& truth_model,
            const FullbodyOptions& options, const SolverOptions& o, bool pelvis_stronger) {
  const Model& m = *model;
  const std::vector<int> points = m.marker_points();
  FabrikSolver solver(model, bench_targets(m, pelvis_stronger), o);
  MotionSettings ms;
  ms.seed = options.seed;
  SyntheticMotion motion(truth_model, ms);
  Posture truth = Posture::rest(m);
  Posture posture = Posture::rest(m);
  std::vector<Eigen::Vector3d> measured(points.size());
  const std::vector<std::uint8_t> visible(points.size(), 1);
  Track t;
  for (int f = 0; f < options.frames; ++f) {
    motion.posture_at(f / options.rate_hz, truth);
    motion.sample(truth, points, options.noise_mm * 1e-3, measured);
    if (f == 0) posture = Posture::rest(m);  // cold start from rest on the first frame
    const auto t0 = std::chrono::steady_clock::now();
    const SolveResult r = solver.solve(measured, visible, posture);
    const auto t1 = std::chrono::steady_clock::now();
    if (f == 0) continue;  // the cold first frame is not part of the tracking figures
    t.times_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    t.rms_mm.push_back(r.rms_m * 1e3);
    t.max_residual_mm = std::max(t.max_residual_mm, r.max_m * 1e3);
    t.iterations.push_back(r.iterations);
    t.passes.push_back(r.passes);
    double sq = 0.0;
    for (const Joint& j : m.joints)
      sq += (posture.point_world_m(m, j.point) - truth.point_world_m(m, j.point)).squaredNorm();
    t.joint_err_mm.push_back(std::sqrt(sq / static_cast<double>(m.joints.size())) * 1e3);
  }
  return t;
}

json track_json(const Track& t) {
  return {{"solve_us",
           {{"median", quantile(t.times_us, 0.5)},
            {"p99", quantile(t.times_us, 0.99)},
            {"max", quantile(t.times_us, 1.0)}}},
          {"iterations_mean", mean(t.iterations)},
          {"passes_mean", mean(t.passes)},
          {"marker_residual_mm", {{"rms_mean", mean(t.rms_mm)}, {"max", t.max_residual_mm}}},
          {"joint_centre_error_mm",
           {{"rms_mean", mean(t.joint_err_mm)}, {"p99", quantile(t.joint_err_mm, 0.99)}}}};
}

}  // namespace

json run_fullbody(const FullbodyOptions& options) {
  const std::string path = options.model.empty() ? "models/fullbody.json" : options.model;
  const auto model = std::make_shared<const Model>(
      load_model(JsonReader::parse(read_config_text(path), path), path));
  const Model& m = *model;
  SolverOptions o;
  o.root = RootMode::free;
  o.segment_fit = options.segment_fit == "paper" ? SegmentFit::paper : SegmentFit::rigid;
  o.tolerance_m = 0.1e-3;        // below the marker noise: stopping is by stall
  o.stall_tolerance_m = 0.1e-3;  // per iteration, a tenth of the marker noise
  o.max_iterations = 50;

  // The same motion (within the joint ranges, if the model has them) tracked
  // with the limits on and, for comparison in the same run, off.
  json out = track_json(track(model, m, options, o, false));
  const bool limits = m.has_joint_limits();
  const auto free_model = std::make_shared<const Model>(without_joint_limits(m));
  if (limits) out["without_limits"] = track_json(track(free_model, m, options, o, false));
  // The embedded daemon config's shape: two priority levels (pelvis markers
  // stronger), the priority loop on.
  SolverOptions prioritized = o;
  prioritized.use_priorities = true;
  out["two_levels"] = track_json(track(model, m, options, prioritized, true));
  if (limits)
    out["two_levels"]["without_limits"] =
        track_json(track(free_model, m, options, prioritized, true));
  out["gap_prediction"] = run_prediction_comparison(model, options, o);
  if (options.calibrated) out["calibrated"] = run_calibrated(options);
  out["benchmark"] = "fullbody";
  out["model"] = {{"name", m.name},
                  {"file", path},
                  {"segments", m.segments.size()},
                  {"markers", m.marker_points().size()},
                  {"joints", m.joints.size()},
                  {"joint_limits", limits}};
  out["motion"] = {{"frames", options.frames},
                   {"rate_hz", options.rate_hz},
                   {"noise_mm", options.noise_mm},
                   {"seed", options.seed}};
  out["solver"] = {{"segment_fit", options.segment_fit},
                   {"root", "free"},
                   {"stall_tolerance_mm", o.stall_tolerance_m * 1e3},
                   {"max_iterations", o.max_iterations},
                   {"warm_start", true}};
  return out;
}

static std::string gap_prediction(const json& g) {
  char gaps[384];
  std::snprintf(gaps, sizeof gaps,
                "through the Tracker, %s\n"
                "  solve per frame   median %.2f us without gap prediction, %.2f us with: "
                "ratio %.3f\n",
                g["occlusion"].get<std::string>().c_str(),
                g["solve_us_median_without"].get<double>(),
                g["solve_us_median_with"].get<double>(), g["ratio"].get<double>());
  return gaps;
}

static std::string calibrated(const json& r) {
  return r.contains("calibrated") ? calibrated_table(r["calibrated"]) : std::string();
}

std::string fullbody_table(const json& r) {
  auto figures = [](const char* title, const json& t) {
    char buf[768];
    std::snprintf(buf, sizeof buf,
                  "%s\n"
                  "  solve per frame   median %.2f us   p99 %.2f us   max %.2f us\n"
                  "  iterations        mean %.2f (reaching passes %.2f)\n"
                  "  marker residual   RMS %.3f mm (mean over frames), max %.3f mm\n"
                  "  joint centres     RMS error %.3f mm against the truth (p99 %.3f mm)\n",
                  title, t["solve_us"]["median"].get<double>(), t["solve_us"]["p99"].get<double>(),
                  t["solve_us"]["max"].get<double>(), t["iterations_mean"].get<double>(),
                  t["passes_mean"].get<double>(), t["marker_residual_mm"]["rms_mean"].get<double>(),
                  t["marker_residual_mm"]["max"].get<double>(),
                  t["joint_centre_error_mm"]["rms_mean"].get<double>(),
                  t["joint_centre_error_mm"]["p99"].get<double>());
    return std::string(buf);
  };
  char head[512];
  std::snprintf(head, sizeof head,
                "Full-body tracking: %d segments, %d markers, %d frames at %g Hz, noise %g mm, %s "
                "fit, warm start\n",
                r["model"]["segments"].get<int>(), r["model"]["markers"].get<int>(),
                r["motion"]["frames"].get<int>(), r["motion"]["rate_hz"].get<double>(),
                r["motion"]["noise_mm"].get<double>(),
                r["solver"]["segment_fit"].get<std::string>().c_str());
  std::string out = head;
  auto ratio = [](const json& with, const json& without) {
    char buf[128];
    std::snprintf(buf, sizeof buf, "  median time with limits / without: %.2f\n",
                  with["solve_us"]["median"].get<double>() /
                      without["solve_us"]["median"].get<double>());
    return std::string(buf);
  };
  const json& two = r["two_levels"];
  if (!r.contains("without_limits")) {
    out += figures("no joint limits in the model; every marker at one level", r);
    out += figures("pelvis markers one level stronger (the default config's shape)", two);
    return out + gap_prediction(r["gap_prediction"]) + calibrated(r);
  }
  out += figures("every marker at one level, with the model's joint limits", r);
  out += figures("the same, joints free", r["without_limits"]);
  out += ratio(r, r["without_limits"]);
  out += figures("pelvis markers one level stronger (the default config's shape), with limits", two);
  out += figures("the same, joints free", two["without_limits"]);
  out += ratio(two, two["without_limits"]);
  return out + gap_prediction(r["gap_prediction"]) + calibrated(r);
}

}  // namespace fabrik::bench
