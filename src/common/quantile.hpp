// Order statistics of samples (timings, residuals), shared by the benchmarks,
// the tools and the evaluations so they all report the same kind of p50/p99.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

namespace fabrik {

// The q-quantile (0..1) by nearest rank; sorts a copy. 0 for no samples.
inline double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, rank == 0 ? 0 : rank - 1)];
}

inline double mean(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x;
  return v.empty() ? 0.0 : s / static_cast<double>(v.size());
}

}  // namespace fabrik
