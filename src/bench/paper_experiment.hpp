// The paper experiment's inputs and timed runs (`fabrik bench paper`): the
// experiment file, one solver timed from the rest posture, and a run as JSON.
#pragma once

#include <Eigen/Core>
#include <chrono>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "solver/model.hpp"
#include "solver/posture.hpp"
#include "solver/solve_types.hpp"

namespace fabrik::bench {

struct Experiment {
  std::shared_ptr<const Model> model;
  // The same body with range-of-motion limits (null if the file names none).
  std::shared_ptr<const Model> limits_model;
  std::vector<Target> targets;
  std::vector<std::string> target_names;
  std::vector<Eigen::Vector3d> positions_m;
  SolverOptions solver;
  int repeats = 1000;
};

// Throws ConfigError. Model paths are relative to the experiment file (or embedded).
Experiment load_experiment(const std::string& path);

struct Run {
  SolveResult result;
  Posture posture;
  std::vector<double> distances_m;
  std::vector<double> times_us;
  double median_us() const;
};

// Solves from the model's rest posture `repeats` times (every run is the same problem).
template <class Solver>
Run time_solver(Solver& solver, const Model& model, const Experiment& e, int repeats) {
  using Clock = std::chrono::steady_clock;
  Run run;
  const std::vector<std::uint8_t> visible(e.targets.size(), 1);
  const Posture start = Posture::rest(model);
  run.posture = start;
  run.times_us.reserve(static_cast<std::size_t>(repeats));
  for (int i = 0; i < repeats; ++i) {
    std::copy(start.segments.begin(), start.segments.end(), run.posture.segments.begin());
    const auto t0 = Clock::now();
    run.result = solver.solve(e.positions_m, visible, run.posture);
    const auto t1 = Clock::now();
    run.times_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
  }
  const auto d = solver.target_distances_m();
  run.distances_m.assign(d.begin(), d.end());
  return run;
}

// Times, status, wrist errors, the final posture (points, and joint angles
// in degrees where the model limits them).
nlohmann::json run_json(const Experiment& e, const Model& model, const Run& run);

}  // namespace fabrik::bench
