// Checks of command-line numbers whose refusals read as a user would say them. CLI11's own
// PositiveNumber printed "Value 0 not in range 0.000000 to 1797693134862315708145...".
#pragma once

#include <CLI/CLI.hpp>
#include <cmath>
#include <string>

namespace fabrik::apps {

// A number above 0 (frames, seconds, a window length).
inline CLI::Validator above_zero() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        double value = 0.0;
        if (!CLI::detail::lexical_cast(text, value) || !std::isfinite(value))
          return "'" + text + "' is not a number";
        if (!(value > 0.0)) return "must be more than 0, not " + text;
        return {};
      },
      "> 0");
}

}  // namespace fabrik::apps
