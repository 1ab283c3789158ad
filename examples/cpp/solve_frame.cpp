// Solve one frame of a model file: every marker of the model is a target, moved 2 cm from
// where the rest posture has it. The model and the plan are made once and shared; each thread
// solves in its own workspace (here two threads, which must agree with each other).
//
//   solve_frame MODEL.json
#include <fabrik/config/load.hpp>
#include <fabrik/solver/solver.hpp>
#include <fabrik/version.hpp>

#include <cstdio>
#include <exception>
#include <memory>
#include <thread>
#include <vector>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s MODEL.json\n", argv[0]);
    return 2;
  }
  std::shared_ptr<const fabrik::Model> model;
  try {
    model = std::make_shared<const fabrik::Model>(fabrik::load_model_file(argv[1]));
  } catch (const std::exception& e) {  // setup errors only: solves return status values
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }

  // One target per model marker, all on priority level 0.
  std::vector<fabrik::Target> targets;
  for (int point : model->marker_points()) targets.push_back({point, 0, 1.0});
  if (targets.empty()) {  // nothing to solve for: said, not a solve of nothing that "converged"
    std::fprintf(stderr,
                 "%s: the model has no markers. Fix: give a model whose segments carry "
                 "markers (e.g. share/fabrik/config/models/fullbody.json)\n",
                 argv[1]);
    return 2;
  }
  fabrik::SolverOptions options;
  options.root = fabrik::RootMode::free;
  options.segment_fit = fabrik::SegmentFit::rigid;  // markers of a segment fitted together
  options.tolerance_m = 1e-4;
  const fabrik::SolverPlan plan(model, targets, options);

  const fabrik::Posture rest = fabrik::Posture::rest(*model);
  std::vector<Eigen::Vector3d> target_world_m;
  for (const fabrik::Target& t : plan.targets())
    target_world_m.push_back(rest.point_world_m(*model, t.point) + Eigen::Vector3d(0.02, 0, 0));
  const std::vector<std::uint8_t> visible(target_world_m.size(), 1);

  fabrik::SolveResult results[2];
  fabrik::Posture postures[2] = {rest, rest};
  std::vector<std::thread> threads;
  for (int k = 0; k < 2; ++k)
    threads.emplace_back([&, k] {
      fabrik::SolverWorkspace workspace(plan);  // per thread
      results[k] = fabrik::solve(plan, workspace, target_world_m, visible, postures[k]);
    });
  for (std::thread& t : threads) t.join();

  // A workspace made for another plan is refused with a status, not undefined behaviour.
  const fabrik::SolverPlan other(model, targets, options);
  fabrik::SolverWorkspace wrong(other);
  fabrik::Posture p = rest;
  const fabrik::SolveResult refused = fabrik::solve(plan, wrong, target_world_m, visible, p);

  std::printf("fabrik %s: model '%s', %zu segments, %zu targets\n", FABRIK_VERSION_STRING,
              model->name.c_str(), model->segments.size(), plan.targets().size());
  std::printf("status %s after %d iterations, rms %.3f mm, max %.3f mm\n",
              std::string(fabrik::to_string(results[0].status)).c_str(), results[0].iterations,
              results[0].rms_m * 1e3, results[0].max_m * 1e3);
  const bool same = results[0].rms_m == results[1].rms_m &&
                    postures[0].segments[0].base_world_m == postures[1].segments[0].base_world_m;
  std::printf("two threads agree: %s; a foreign workspace gives: %s\n", same ? "yes" : "NO",
              std::string(fabrik::to_string(refused.status)).c_str());
  const bool ok = same && results[0].status == fabrik::SolveStatus::converged &&
                  refused.status == fabrik::SolveStatus::wrong_workspace;
  return ok ? 0 : 1;
}
