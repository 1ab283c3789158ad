// Solver settings from JSON ("solver" objects in experiments and daemon
// configs). Lengths are given in millimetres in JSON, as `*_mm` keys.
#pragma once

#include "json_reader.hpp"
#include "solver/solve_types.hpp"

namespace fabrik {

SolverOptions read_solver_options(const JsonReader& solver, SolverOptions defaults = {});
// The inverse, for configs fabrik writes (`fabrik calibrate`): the keys a daemon config's
// "solver" object names, lengths in millimetres.
nlohmann::ordered_json solver_options_json(const SolverOptions& options);

}  // namespace fabrik
