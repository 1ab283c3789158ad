// A number with a fixed count of decimals, character for character what
// std::to_chars(..., std::chars_format::fixed, decimals) writes (the
// correctly rounded decimal of the binary value), several times faster for
// the numbers a pose carries. The pose's numbers were most of its encoding
// time (docs/pipeline.md). The value times 10^decimals is rounded to an
// integer; where that product's rounding error could change the result (a
// tie within 2^-9, or a product of 2^40 and more) it defers to to_chars.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>

namespace fabrik::wire {

inline std::to_chars_result to_fixed_chars(char* first, char* last, double v, int decimals) {
  constexpr double kScale[] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
  constexpr std::uint64_t kScaleInt[] = {1,      10,      100,      1000,      10000,
                                         100000, 1000000, 10000000, 100000000, 1000000000};
  const auto exact = [&] { return std::to_chars(first, last, v, std::chars_format::fixed, decimals); };
  // 1 sign + 16 integer digits + 1 point + 9 decimals fit.
  if (decimals < 0 || decimals > 9 || last - first < 32 || !std::isfinite(v)) return exact();
  const double scaled = std::fabs(v) * kScale[decimals];
  // |scaled - exact product| <= half an ulp of scaled: 2^-14 below 2^40;
  // nothing with no decimals (the product is the value itself).
  if (!(scaled < (decimals == 0 ? 0x1p53 : 0x1p40))) return exact();
  const double whole = std::floor(scaled);
  const double fraction = scaled - whole;  // exact (Sterbenz)
  if (decimals == 0 ? fraction == 0.5 : std::fabs(fraction - 0.5) < 0x1p-9) return exact();
  const std::uint64_t n = static_cast<std::uint64_t>(whole) + (fraction > 0.5 ? 1 : 0);
  char* p = first;
  if (std::signbit(v)) *p++ = '-';  // as to_chars: -0.0 and small negatives keep their sign
  const std::uint64_t scale = kScaleInt[decimals];
  p = std::to_chars(p, last, n / scale).ptr;
  if (decimals > 0) {
    *p++ = '.';
    std::uint64_t digits = n % scale;
    for (int i = decimals - 1; i >= 0; --i) {
      p[i] = static_cast<char>('0' + digits % 10);
      digits /= 10;
    }
    p += decimals;
  }
  return {p, std::errc()};
}

}  // namespace fabrik::wire
