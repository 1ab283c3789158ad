// Benchmarks behind `fabrik bench ...`: they print figures, they do not pass
// or fail (except that a broken setup is an error).
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "solver/model.hpp"
#include "solver/solve_types.hpp"

namespace fabrik::bench {

struct PaperOptions {
  std::string experiment = "paper_experiment.json";  // file, or the embedded default
  int repeats = 0;                                   // 0: the experiment's own count
};
// The paper's experiment: FABRIK without and with priorities against the
// Jacobian transpose, from the same start; times, errors, posture checks.
nlohmann::json run_paper(const PaperOptions& options);
std::string paper_table(const nlohmann::json& result);

struct FullbodyOptions {
  int frames = 2000;
  double rate_hz = 100.0;
  double noise_mm = 1.0;
  unsigned seed = 1;
  std::string segment_fit = "rigid";
  std::string model;  // a model file; empty: the built-in config/models/fullbody.json
};
// Tracking of the built-in full-body model on smooth synthetic motion; a
// model with joint limits is tracked with them and, in the same run, without.
nlohmann::json run_fullbody(const FullbodyOptions& options);
// Per-frame solve time through the Tracker under a moving occlusion, gap
// prediction off and on, interleaved (prediction_bench.cpp).
nlohmann::json run_prediction_comparison(const std::shared_ptr<const Model>& model,
                                         const FullbodyOptions& options, const SolverOptions& o);
std::string fullbody_table(const nlohmann::json& result);

}  // namespace fabrik::bench
