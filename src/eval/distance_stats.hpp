// Small statistics shared by the evaluations (internal to src/eval).
#pragma once

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace fabrik::eval {

inline double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Running RMS and max of distances.
struct DistanceStats {
  double sq = 0.0, max = 0.0;
  int n = 0;
  std::string max_name;
  void add(double d, const std::string& name = {}) {
    sq += d * d;
    ++n;
    if (d > max || n == 1) max = d, max_name = name;
  }
  double rms() const { return n ? std::sqrt(sq / n) : 0.0; }
};

}  // namespace fabrik::eval
