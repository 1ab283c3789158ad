// Runs the `fabrik` program under test (FABRIK_PATH) from a test, bounded in
// time, and reads files it wrote.
#pragma once

#include <catch2/catch.hpp>
#include <chrono>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "process.hpp"

namespace fabrik::test {

// Runs `fabrik ARGS...` with stdout to `stdout_path`; its exit code and stderr.
// Fails the test (and kills the process) after `limit`.
inline std::pair<int, std::string> run_fabrik(const std::vector<std::string>& args,
                                              const std::string& stdout_path = "/dev/null",
                                              std::chrono::seconds limit = std::chrono::seconds(60)) {
  std::string command = "exec '" + std::string(FABRIK_PATH) + "'";
  for (const std::string& a : args) command += " '" + a + "'";
  command += " > '" + stdout_path + "'";
  Process p({"/bin/sh", "-c", command});
  const std::optional<int> code = p.wait(limit);
  REQUIRE(code.has_value());
  return {*code, p.stderr_text()};
}

inline std::string slurp(const std::string& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace fabrik::test
