// Solver settings from JSON ("solver" objects in experiments and daemon
// configs). Lengths are given in millimetres in JSON, as `*_mm` keys.
#pragma once

#include "json_reader.hpp"
#include "solver/solve_types.hpp"

namespace fabrik {

SolverOptions read_solver_options(const JsonReader& solver, SolverOptions defaults = {});

}  // namespace fabrik
