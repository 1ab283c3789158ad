// A number with a fixed count of decimals, character for character what
// std::to_chars(..., std::chars_format::fixed, decimals) writes (the
// correctly rounded decimal of the binary value), several times faster for
// the numbers a pose carries. The pose's numbers were most of its encoding
// time (docs/pipeline.md). The value times 10^decimals is rounded to an
// integer; where that product's rounding error could change the result (a
// tie within 2^-9, or a product of 2^40 and more) it defers to to_chars.
// Each count of decimals is its own instance, so every division is by a
// constant (a multiplication): a division by a variable was a third of the
// time per number.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace fabrik::wire {

namespace fixed_detail {

inline constexpr char kPairs[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

constexpr std::uint64_t pow10(int d) { return d == 0 ? 1 : 10 * pow10(d - 1); }

// Exactly D digits of `digits` (< 10^D), two at a time from the right.
template <int D>
inline char* write_decimals(char* p, std::uint64_t digits) {
  for (int i = D; i >= 2; i -= 2) {
    std::memcpy(p + i - 2, kPairs + 2 * (digits % 100), 2);
    digits /= 100;
  }
  if constexpr (D % 2 == 1) p[0] = static_cast<char>('0' + digits);
  return p + D;
}

// n in decimal (to_chars' own, not inlined, was a third of the time per number).
[[gnu::always_inline]] inline char* write_uint(char* p, std::uint64_t n) {
  int len = 1;
  for (std::uint64_t t = n; t >= 10; t /= 10) ++len;
  char* q = p + len;
  while (n >= 100) {
    q -= 2;
    std::memcpy(q, kPairs + 2 * (n % 100), 2);
    n /= 100;
  }
  if (n >= 10)
    std::memcpy(q - 2, kPairs + 2 * n, 2);
  else
    q[-1] = static_cast<char>('0' + n);
  return p + len;
}

template <int D>
inline std::to_chars_result to_fixed(char* first, char* last, double v) {
  const double scaled = std::fabs(v) * static_cast<double>(pow10(D));
  // |scaled - exact product| <= half an ulp of scaled: 2^-14 below 2^40;
  // nothing with no decimals (the product is the value itself).
  if (!(scaled < (D == 0 ? 0x1p53 : 0x1p40)))
    return std::to_chars(first, last, v, std::chars_format::fixed, D);
  // Truncation is the floor here (0 <= scaled < 2^53) and needs no libm call; signed, it is
  // one instruction each way.
  const auto whole = static_cast<std::int64_t>(scaled);
  const double fraction = scaled - static_cast<double>(whole);  // exact (Sterbenz)
  if (D == 0 ? fraction == 0.5 : std::fabs(fraction - 0.5) < 0x1p-9)
    return std::to_chars(first, last, v, std::chars_format::fixed, D);
  const auto n = static_cast<std::uint64_t>(whole) + (fraction > 0.5 ? 1 : 0);
  char* p = first;
  if (std::signbit(v)) *p++ = '-';  // as to_chars: -0.0 and small negatives keep their sign
  p = write_uint(p, n / pow10(D));
  if constexpr (D > 0) {
    *p++ = '.';
    p = write_decimals<D>(p, n % pow10(D));
  }
  return {p, std::errc()};
}

}  // namespace fixed_detail

inline std::to_chars_result to_fixed_chars(char* first, char* last, double v, int decimals) {
  using namespace fixed_detail;
  // 1 sign + 16 integer digits + 1 point + 9 decimals fit.
  if (last - first < 32 || !std::isfinite(v))
    return std::to_chars(first, last, v, std::chars_format::fixed, decimals);
  switch (decimals) {
    case 0: return to_fixed<0>(first, last, v);
    case 1: return to_fixed<1>(first, last, v);
    case 2: return to_fixed<2>(first, last, v);
    case 3: return to_fixed<3>(first, last, v);
    case 4: return to_fixed<4>(first, last, v);
    case 5: return to_fixed<5>(first, last, v);
    case 6: return to_fixed<6>(first, last, v);
    case 7: return to_fixed<7>(first, last, v);
    case 8: return to_fixed<8>(first, last, v);
    case 9: return to_fixed<9>(first, last, v);
    default: return std::to_chars(first, last, v, std::chars_format::fixed, decimals);
  }
}

}  // namespace fabrik::wire
