// What a marker trial the readers return promises (src/io/marker_trial.hpp).
#pragma once

#include <cmath>

#include "fuzz_check.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::fuzz {

inline void require_valid_trial(const io::MarkerTrial& trial) {
  require(trial.labels.empty() ? trial.positions_m.empty()
                               : trial.positions_m.size() % trial.labels.size() == 0,
          "positions are not frames x markers");
  require(std::isfinite(trial.rate_hz) && trial.rate_hz > 0.0, "rate is not a positive number");
}

}  // namespace fabrik::fuzz
