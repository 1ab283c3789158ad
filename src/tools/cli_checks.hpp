// Checks of command-line values whose refusals read as a user would say them, for every
// command's options. CLI11's own PositiveNumber printed "Value 0 not in range
// 0.000000 to 1797693134862315708145...", and its Range lets NaN through (every comparison with
// NaN is false), so `--rate nan` passed "FLOAT in [1 - 100000]".
#pragma once

#include <CLI/CLI.hpp>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <string>
#include <string_view>
#include <system_error>
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
          // CLI11's Range said "Value abc not in range 0.000000 to 1000000.000000".
          if (!CLI::detail::lexical_cast(text, value) || std::isnan(value))
            return "'" + text + "' is not a number";
        }
        return inner(text);
      },
      inner.get_description());
}

namespace details {

// Before CLI11 converts a whole number, which it does with strtoll base 0: `--frames 010` was
// 8 (octal) and `--frames 1e3` "not in range". Decimal digits lose their leading zeros, and a
// number written with a point or an exponent is taken when it is whole and exact as a double
// (below 2^53). Hexadecimal (0x...) is written on purpose and left to CLI11. Blanks and a
// second sign, which strtoll would skip or take, are refused. With `at_least_zero` (an unsigned
// option) a number below 0 is refused here, quoted as written: CLI11's own refusal came after
// the rewriting ("Could not convert: --seed = -1000" for `-1e3`).
inline std::string whole_number_in_decimal(std::string& text, bool at_least_zero) {
  const std::string not_whole = "'" + text + "' is not a whole number";
  const std::string below_zero = "'" + text + "' is below 0: give a whole number of 0 or more";
  const std::size_t sign = !text.empty() && (text[0] == '+' || text[0] == '-') ? 1 : 0;
  const std::string_view digits = std::string_view(text).substr(sign);
  if (digits.empty() || digits[0] == '+' || digits[0] == '-' ||
      text.find_first_of(" \t\n\r\f\v") != std::string::npos)
    return not_whole;
  if (digits.find_first_not_of("0123456789") == std::string_view::npos) {
    if (at_least_zero && text[0] == '-' && digits.find_first_not_of('0') != std::string_view::npos)
      return below_zero;
    const std::size_t first = std::min(digits.find_first_not_of('0'), digits.size() - 1);
    text = text.substr(0, sign) + std::string(digits.substr(first));
    return {};
  }
  if (digits.size() > 1 && digits[0] == '0' && (digits[1] == 'x' || digits[1] == 'X')) return {};
  double value = 0.0;
  const char* end = text.data() + text.size();
  const auto [stop, error] = std::from_chars(text.data() + (text[0] == '+' ? 1 : 0), end, value);
  if (error != std::errc() || stop != end || !std::isfinite(value)) return {};
  if (value != std::floor(value)) return not_whole;
  if (at_least_zero && value < 0.0) return below_zero;
  constexpr double kExact = 9007199254740992.0;  // 2^53: every whole double below it is exact
  if (!(std::abs(value) < kExact))
    return "'" + text + "' is too large to write with a point or an exponent: write its digits";
  text = std::to_string(static_cast<long long>(value));
  return {};
}

}  // namespace details

// Every option of every command of `app`, as a user expects of them all: an empty value
// (`--config ""`, `--seed ""`, an unset shell variable) is refused instead of read as "the
// default", as no file or as 0, and whole numbers are read in decimal
// (details::whole_number_in_decimal). Call once the commands are added, before the parse.
inline void refuse_surprising_values(CLI::App& app) {
  for (CLI::Option* opt : app.get_options({})) {
    if (opt->get_type_size_max() == 0) continue;  // a flag
    const std::string type = opt->get_type_name();
    const std::string kind = type.substr(0, type.find_first_of(": "));
    if (kind == "INT" || kind == "UINT") {
      const bool at_least_zero = kind == "UINT";
      opt->transform(CLI::Validator(
          [at_least_zero](std::string& text) {
            return details::whole_number_in_decimal(text, at_least_zero);
          },
          ""));
    }
    const std::string name = opt->get_name();
    // A positional is named by its help's word ("files"), which CLI11 puts before the message.
    const std::string fix =
        !opt->nonpositional() ? (opt->get_expected_max() > 1
                                     ? "an empty value (\"\") was given. Fix: give each a value"
                                     : "is empty (\"\"). Fix: give a value")
        : opt->get_required()
            ? "is empty. Fix: give a value"
            : "is empty. Fix: give a value, or leave out " + name + " for its default";
    // A transform goes before every check added so far: this one runs first.
    opt->transform(CLI::Validator(
        [fix](std::string& text) -> std::string { return text.empty() ? fix : std::string(); },
        ""));
  }
  for (CLI::App* sub : app.get_subcommands({})) refuse_surprising_values(*sub);
}

}  // namespace fabrik::cli
