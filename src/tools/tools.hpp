// The `fabrik` subcommands of this library, registered on the CLI11 app. Each command runs
// from its subcommand's callback; a failure prints "fabrik <command>: <reason>" and exits 2.
#pragma once

#include <CLI/CLI.hpp>

namespace fabrik::tools {

void add_replay_command(CLI::App& app);
void add_watch_command(CLI::App& app);
void add_synth_command(CLI::App& app);
void add_sim_command(CLI::App& app);

// Ctrl-C and SIGTERM set a flag instead of ending the process: a command that runs until
// stopped (replay, watch, sim, view) polls stop_signalled() and ends with its summary.
void catch_stop_signals();
bool stop_signalled();

// All of the above.
inline void add_tool_commands(CLI::App& app) {
  add_replay_command(app);
  add_watch_command(app);
  add_synth_command(app);
  add_sim_command(app);
}

}  // namespace fabrik::tools
