// CLI11's own messages quote the offending argument ("--log-level: \xff not in
// {...}"): they reach stderr through safe_lines like every other text a user
// gave, so no raw byte that is not UTF-8 or a control character gets out.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "common/safe_text.hpp"

namespace fabrik::apps {

// app.exit(e): help and version on stdout as CLI11 writes them, its error text made safe.
// The exit code: 0 for help and version; 2 for a command line CLI11 refused, as for every
// other wrong input (CLI11 numbers each kind from 100 up, which no user of ours expects);
// a command's own CLI::RuntimeError keeps its code.
inline int exit_safely(CLI::App& app, const CLI::Error& e) {
  std::ostringstream err;
  const int code = app.exit(e, std::cout, err);
  const std::string text = err.str();
  if (!text.empty()) std::fputs(safe_lines(text).c_str(), stderr);
  // (CLI11's RuntimeError is a ParseError too: it is told apart first.)
  if (code != 0 && dynamic_cast<const CLI::RuntimeError*>(&e) == nullptr &&
      dynamic_cast<const CLI::ParseError*>(&e) != nullptr)
    return 2;
  return code;
}

}  // namespace fabrik::apps
