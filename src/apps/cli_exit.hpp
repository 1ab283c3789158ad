// CLI11's own messages quote the offending argument ("--log-level: \xff not in
// {...}"): they reach stderr through safe_lines like every other text a user
// gave, so no raw byte that is not UTF-8 or a control character gets out.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "common/safe_text.hpp"

namespace fabrik::apps {

// False, with a message on stderr, when what a program wrote to standard output was lost (a
// full disk, a reader that closed): an error, as for a file. std::cout shares stdout's buffer
// (synced with stdio). The reason, errno, is gone by now: the failed write was an earlier one.
inline bool standard_output_written(const char* program) {
  std::cout.flush();
  if (std::cout && std::fflush(stdout) == 0 && !std::ferror(stdout)) return true;
  std::fprintf(stderr,
               "%s: writing the standard output failed (a full disk, or a reader that closed?)\n",
               program);
  return false;
}

// app.exit(e): help and version on stdout as CLI11 writes them, its error text made safe.
// The exit code: 0 for help and version (2 if they could not be written); 2 for a command
// line CLI11 refused, as for every other wrong input (CLI11 numbers each kind from 100 up,
// which no user of ours expects); a command's own CLI::RuntimeError keeps its code.
inline int exit_safely(CLI::App& app, const CLI::Error& e, const char* program) {
  std::ostringstream err;
  const int code = app.exit(e, std::cout, err);
  const std::string text = err.str();
  if (!text.empty()) std::fputs(safe_lines(text).c_str(), stderr);
  if (code == 0 && !standard_output_written(program)) return 2;
  // (CLI11's RuntimeError is a ParseError too: it is told apart first.)
  if (code != 0 && dynamic_cast<const CLI::RuntimeError*>(&e) == nullptr &&
      dynamic_cast<const CLI::ParseError*>(&e) != nullptr)
    return 2;
  return code;
}

// The leading words of a command line that name no command of `app`, said as such: CLI11
// answers `fabrik nosuch` and `fabrik bench nosuch` with "A subcommand is required". Empty when
// every word up to the first option or argument names a command.
inline std::string unknown_command(const CLI::App& app, int argc, const char* const* argv) {
  const CLI::App* at = &app;
  std::string said = "fabrik";
  for (int i = 1; i < argc; ++i) {
    const std::string_view word = argv[i];
    const std::vector<const CLI::App*> commands = at->get_subcommands({});
    if (word.empty() || word[0] == '-' || commands.empty()) break;
    const CLI::App* next = nullptr;
    std::string names;
    for (const CLI::App* c : commands) {
      if (c->check_name(std::string(word))) next = c;
      names += (names.empty() ? "" : ", ") + c->get_name();
    }
    if (next == nullptr)
      return said + ": '" + std::string(word) + "' is not a command; the commands: " + names +
             "\nRun with --help for more information.\n";
    at = next;
    said += " " + std::string(word);
  }
  return {};
}

}  // namespace fabrik::apps
