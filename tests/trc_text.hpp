// Small TRC files written as text, for tests of what the reader refuses or
// warns about (labels, Time column) that write_trc would never write.
#pragma once

#include <string>
#include <vector>

namespace fabrik::test {

// Two markers named `a` and `b` at `rate` Hz (100 by default) in mm, one row per time in
// `times` (frames from `first_frame`, rows from line 6).
inline std::string two_marker_trc(const std::string& a, const std::string& b,
                                  const std::vector<std::string>& times,
                                  const std::string& rate = "100", int first_frame = 1) {
  std::string text =
      "PathFileType\t4\t(X/Y/Z)\tx.trc\n"
      "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\n" +
      rate + "\t" + rate + "\t" + std::to_string(times.size()) +
      "\t2\tmm\n"
      "Frame#\tTime\t" +
      a + "\t\t\t" + b +
      "\t\t\n"
      "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n";
  for (std::size_t f = 0; f < times.size(); ++f)
    text += std::to_string(first_frame + static_cast<int>(f)) + "\t" + times[f] +
            "\t1\t2\t3\t4\t5\t6\n";
  return text;
}

}  // namespace fabrik::test
