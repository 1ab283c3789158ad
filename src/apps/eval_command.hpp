// `fabrik eval walk|gaps|reduction|synthetic|angles`: accuracy evaluations (src/eval).
#pragma once

#include <CLI/CLI.hpp>

namespace fabrik::apps {
void add_eval_command(CLI::App& app);
}
