// Benchmarks behind `fabrik bench ...`: they print figures, they do not pass
// or fail (except that a broken setup is an error).
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

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
  // The figure users get (template_bench.cpp): a daemon config as `fabrik calibrate` writes
  // it. `config` names one; empty: `template_path` calibrated on `static_trial` (a generated
  // static trial when that file is absent). Tracked on synthetic motion at each of `speeds`
  // (times the default cycle frequency) and on each of `trials` that exists and has at least
  // half the config's markers, every `steps`-th frame; each with the subtree carry on and off
  // in alternate frames (the carry's cost). `calibrated` false skips it.
  bool calibrated = true;
  std::string config;
  std::string template_path = "config/templates/gait2354.json";
  std::string static_trial = "../shared/data/subject01_static.trc";
  std::vector<std::string> trials = {"../shared/data/subject01_walk1.trc"};
  std::vector<int> steps = {1, 2, 3};
  std::vector<double> speeds = {1.0, 3.0};
};
// Tracking of the built-in full-body model on smooth synthetic motion; a
// model with joint limits is tracked with them and, in the same run, without.
nlohmann::json run_fullbody(const FullbodyOptions& options);
// Per-frame solve time through the Tracker under a moving occlusion, gap
// prediction off and on, interleaved (prediction_bench.cpp).
nlohmann::json run_prediction_comparison(const std::shared_ptr<const Model>& model,
                                         const FullbodyOptions& options, const SolverOptions& o);
std::string fullbody_table(const nlohmann::json& result);
// The calibrated config's runs (template_bench.cpp), also part of run_fullbody's result.
nlohmann::json run_calibrated(const FullbodyOptions& options);
std::string calibrated_table(const nlohmann::json& result);

}  // namespace fabrik::bench
