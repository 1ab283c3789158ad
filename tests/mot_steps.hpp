// Steps between consecutive rows of an OpenSim table, over every column but
// time: a coordinate that wraps at +-180 deg steps by about 360. Degrees for
// rotations; translations are metres, whose steps are far smaller.
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

// The largest jump: a step between consecutive rows that is not part of a
// sustained movement, i.e. neither neighbouring step of the same column goes
// the same way by at least half as much. A wrap (about 360 deg) or a snap to
// a joint bound is a jump; a toe swinging 45 deg over five frames at 60 Hz,
// 11 deg in its fastest frame, is not.
inline TableStep largest_jump(const io::OpenSimTable& t) {
  TableStep worst;
  for (std::size_t c = 1; c < t.columns.size(); ++c)
    for (std::size_t row = 1; row < t.rows; ++row) {
      const double d = t.at(row, c) - t.at(row - 1, c);
      const auto sustains = [&](std::size_t r) {  // the step into row r
        if (r < 1 || r >= t.rows) return false;
        const double e = t.at(r, c) - t.at(r - 1, c);
        return e * d > 0.0 && std::abs(e) >= 0.5 * std::abs(d);
      };
      if (sustains(row - 1) || sustains(row + 1)) continue;
      if (std::abs(d) > worst.step) worst = {std::abs(d), t.columns[c], t.time_s[row]};
    }
  return worst;
}

// The bound: no coordinate jumps more than 10 deg between frames.
inline constexpr double kMaxCoordinateStepDeg = 10.0;

}  // namespace fabrik::test
