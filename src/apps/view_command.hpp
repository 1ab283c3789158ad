// `fabrik view`: the browser view of fabrikd's poses (src/view/), or of a trial tracked
// offline (--trial FILE --config C).
#pragma once

#include <CLI/CLI.hpp>

namespace fabrik::apps {

void add_view_command(CLI::App& app);

}  // namespace fabrik::apps
