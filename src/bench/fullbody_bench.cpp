// `fabrik bench fullbody`: the built-in full-body model tracking smooth
// synthetic motion with marker noise, warm-started frame to frame.
#include <chrono>
#include <cstdio>

#include "bench.hpp"
#include "config/json_reader.hpp"
#include "config/model_loader.hpp"
#include "config/resources.hpp"
#include "solver/fabrik_solver.hpp"
#include "stats.hpp"
#include "synth/synthetic_motion.hpp"

namespace fabrik::bench {

using nlohmann::json;

json run_fullbody(const FullbodyOptions& options) {
  const std::string path = "models/fullbody.json";
  const Model m = load_model(JsonReader::parse(read_config_text(path), path), path);
  const std::vector<int> points = m.marker_points();
  std::vector<Target> targets;
  for (int p : points) targets.push_back({p, 0, 1.0});
  SolverOptions o;
  o.root = RootMode::free;
  o.segment_fit = options.segment_fit == "paper" ? SegmentFit::paper : SegmentFit::rigid;
  o.tolerance_m = 0.1e-3;        // below the marker noise: stopping is by stall
  o.stall_tolerance_m = 0.1e-3;  // per iteration, a tenth of the marker noise
  o.max_iterations = 50;
  FabrikSolver solver(m, targets, o);

  MotionSettings ms;
  ms.seed = options.seed;
  SyntheticMotion motion(m, ms);
  Posture truth = Posture::rest(m);
  Posture posture = Posture::rest(m);
  std::vector<Eigen::Vector3d> measured(points.size());
  const std::vector<std::uint8_t> visible(points.size(), 1);
  std::vector<double> times_us, rms_mm, iterations, passes, joint_err_mm;
  double max_residual_mm = 0.0;
  for (int f = 0; f < options.frames; ++f) {
    motion.posture_at(f / options.rate_hz, truth);
    motion.sample(truth, points, options.noise_mm * 1e-3, measured);
    if (f == 0) posture = Posture::rest(m);  // cold start from rest on the first frame
    const auto t0 = std::chrono::steady_clock::now();
    const SolveResult r = solver.solve(measured, visible, posture);
    const auto t1 = std::chrono::steady_clock::now();
    if (f == 0) continue;  // the cold first frame is not part of the tracking figures
    times_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    rms_mm.push_back(r.rms_m * 1e3);
    max_residual_mm = std::max(max_residual_mm, r.max_m * 1e3);
    iterations.push_back(r.iterations);
    passes.push_back(r.passes);
    double sq = 0.0;
    for (const Joint& j : m.joints)
      sq += (posture.point_world_m(m, j.point) - truth.point_world_m(m, j.point)).squaredNorm();
    joint_err_mm.push_back(std::sqrt(sq / static_cast<double>(m.joints.size())) * 1e3);
  }
  json out;
  out["benchmark"] = "fullbody";
  out["model"] = {{"name", m.name},
                  {"segments", m.segments.size()},
                  {"markers", points.size()},
                  {"joints", m.joints.size()}};
  out["motion"] = {{"frames", options.frames},
                   {"rate_hz", options.rate_hz},
                   {"noise_mm", options.noise_mm},
                   {"seed", options.seed}};
  out["solver"] = {{"segment_fit", options.segment_fit},
                   {"root", "free"},
                   {"stall_tolerance_mm", o.stall_tolerance_m * 1e3},
                   {"max_iterations", o.max_iterations},
                   {"warm_start", true}};
  out["solve_us"] = {{"median", quantile(times_us, 0.5)},
                     {"p99", quantile(times_us, 0.99)},
                     {"max", quantile(times_us, 1.0)}};
  out["iterations_mean"] = mean(iterations);
  out["passes_mean"] = mean(passes);
  out["marker_residual_mm"] = {{"rms_mean", mean(rms_mm)}, {"max", max_residual_mm}};
  out["joint_centre_error_mm"] = {{"rms_mean", mean(joint_err_mm)},
                                  {"p99", quantile(joint_err_mm, 0.99)}};
  return out;
}

std::string fullbody_table(const json& r) {
  char buf[1024];
  std::snprintf(buf, sizeof buf,
                "Full-body tracking: %d segments, %d markers, %d frames at %g Hz, noise %g mm, %s "
                "fit, warm start\n"
                "  solve per frame   median %.2f us   p99 %.2f us   max %.2f us\n"
                "  iterations        mean %.2f (reaching passes %.2f)\n"
                "  marker residual   RMS %.3f mm (mean over frames), max %.3f mm\n"
                "  joint centres     RMS error %.3f mm against the truth (p99 %.3f mm)\n",
                r["model"]["segments"].get<int>(), r["model"]["markers"].get<int>(),
                r["motion"]["frames"].get<int>(), r["motion"]["rate_hz"].get<double>(),
                r["motion"]["noise_mm"].get<double>(),
                r["solver"]["segment_fit"].get<std::string>().c_str(),
                r["solve_us"]["median"].get<double>(), r["solve_us"]["p99"].get<double>(),
                r["solve_us"]["max"].get<double>(), r["iterations_mean"].get<double>(),
                r["passes_mean"].get<double>(), r["marker_residual_mm"]["rms_mean"].get<double>(),
                r["marker_residual_mm"]["max"].get<double>(),
                r["joint_centre_error_mm"]["rms_mean"].get<double>(),
                r["joint_centre_error_mm"]["p99"].get<double>());
  return buf;
}

}  // namespace fabrik::bench
