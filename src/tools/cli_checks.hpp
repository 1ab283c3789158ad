// Checks of command-line numbers whose refusals read as a user would say them, for every
// command's options. CLI11's own PositiveNumber printed "Value 0 not in range
// 0.000000 to 1797693134862315708145...", and its Range lets NaN through (every comparison with
// NaN is false), so `--rate nan` passed "FLOAT in [1 - 100000]".
#pragma once

#include <CLI/CLI.hpp>
#include <cmath>
#include <string>
#include <type_traits>

namespace fabrik::cli {

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

// CLI::Range(lo, hi), NaN refused; shown in --help as CLI11 shows its Range ("FLOAT in [a - b]").
template <class T>
CLI::Validator range(T lo, T hi) {
  const CLI::Range inner(lo, hi);
  return CLI::Validator(
      [inner](std::string& text) -> std::string {
        if constexpr (std::is_floating_point_v<T>) {
          T value{};
          if (CLI::detail::lexical_cast(text, value) && std::isnan(value))
            return "'" + text + "' is not a number";
        }
        return inner(text);
      },
      inner.get_description());
}

}  // namespace fabrik::cli
