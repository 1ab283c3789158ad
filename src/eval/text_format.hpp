// Number and column formatting for the evaluation tables (internal to src/eval).
#pragma once

#include <cstdio>
#include <string>

namespace fabrik::eval {

inline std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}
inline std::string mm2(double metres) {
  return fmt("%.2f", metres * 1e3);
}
inline std::string pad(std::string s, std::size_t width, bool right = false) {
  if (s.size() >= width) return s + " ";
  const std::string fill(width - s.size(), ' ');
  return right ? fill + s + " " : s + fill + " ";
}

}  // namespace fabrik::eval
