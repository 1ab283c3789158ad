// `fabrik calibrate`: a model template and a static trial -> a daemon config
// with the subject's model inline (see docs/calibration.md).
#pragma once

#include <CLI/CLI.hpp>

namespace fabrik {

// Registers the subcommand; it runs from its own callback and exits with code
// 2 (via CLI::RuntimeError) when calibration fails.
void add_calibrate_command(CLI::App& app);

}  // namespace fabrik
