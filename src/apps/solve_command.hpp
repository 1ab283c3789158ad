// `fabrik solve`: offline tracking of a TRC/C3D trial with a daemon config.
#pragma once

#include <CLI/CLI.hpp>

namespace fabrik::apps {
void add_solve_command(CLI::App& app);
}
