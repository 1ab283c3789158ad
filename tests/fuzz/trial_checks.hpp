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
  // A file without points (analog only) may have no point rate: it has no
  // markers to time, and the commands refuse it (io::require_marker_data).
  require(trial.labels.empty() || io::plausible_frame_rate(trial.rate_hz),
          "a trial with markers has a rate outside 0.001 Hz to 1 MHz");
}

}  // namespace fabrik::fuzz
