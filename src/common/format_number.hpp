// One number through a printf format ("%.2f mm"), for tables and messages.
#pragma once

#include <cstdio>
#include <string>

namespace fabrik {

inline std::string format_number(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

}  // namespace fabrik
