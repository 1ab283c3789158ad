// The largest step between consecutive rows of an OpenSim table, over every
// column but time: a coordinate that wraps at +-180 deg steps by about 360.
// Degrees for rotations; translations are metres, whose steps are far smaller.
#pragma once

#include <cmath>
#include <string>

#include "io/opensim_table.hpp"

namespace fabrik::test {

struct TableStep {
  double step = 0.0;
  std::string column;
  double time_s = 0.0;  // of the later row
};

inline TableStep largest_step(const io::OpenSimTable& t) {
  TableStep worst;
  for (std::size_t c = 1; c < t.columns.size(); ++c)
    for (std::size_t row = 1; row < t.rows; ++row) {
      const double d = std::abs(t.at(row, c) - t.at(row - 1, c));
      if (d > worst.step) worst = {d, t.columns[c], t.time_s[row]};
    }
  return worst;
}

// The bound: no coordinate steps more than 10 deg between frames.
inline constexpr double kMaxCoordinateStepDeg = 10.0;

}  // namespace fabrik::test
