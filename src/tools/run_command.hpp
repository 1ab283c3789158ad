// The one way a `fabrik` subcommand reports failure: a single line on stderr
// naming the command, and exit code 2 (through CLI11, caught in main).
#pragma once

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <string>

namespace fabrik::tools {

template <class F>
void run_command(const std::string& name, F&& body) {
  try {
    body();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fabrik %s: %s\n", name.c_str(), e.what());
    throw CLI::RuntimeError(2);
  }
}

}  // namespace fabrik::tools
