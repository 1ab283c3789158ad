// What the paper experiment's final postures must be: the geometric optimum
// of the prioritized posture (the chain to the strong wrist straight at its
// target, the weak wrist as close as that allows) and the named checks
// against it; and, with range-of-motion limits, that every joint ends in range.
#pragma once

#include <nlohmann/json.hpp>

#include "paper_experiment.hpp"

namespace fabrik::bench {

// A named check: {pass, value, limit, unit, meaning}.
nlohmann::json check(bool pass, double value, double limit, const char* unit, const char* what);

// {"geometric_minimum_mm": ..., "checks": {...}, "root_m": [...]} for the
// unlimited runs without and with priorities.
nlohmann::json posture_checks(const Experiment& e, const Run& flat, const Run& prioritized);

// Largest distance, in degrees, of any limited joint outside its range.
double max_limit_excess_deg(const Model& model, const Posture& posture);

}  // namespace fabrik::bench
