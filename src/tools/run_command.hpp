// The one way a `fabrik` subcommand reports failure: a single line on stderr
// naming the command, and exit code 2 (through CLI11, caught in main).
#pragma once

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <string>

#include "common/safe_text.hpp"

namespace fabrik::tools {

template <class F>
void run_command(const std::string& name, F&& body) {
  try {
    body();
  } catch (const std::exception& e) {
    // Messages quote file names, endpoints and labels as given: made safe text.
    std::fprintf(stderr, "fabrik %s: %s\n", name.c_str(), safe_lines(e.what()).c_str());
    throw CLI::RuntimeError(2);
  }
}

}  // namespace fabrik::tools
