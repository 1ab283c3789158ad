#include "trajectory_filter.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

namespace fabrik {

Butterworth2 Butterworth2::low_pass(double cutoff_hz, double rate_hz) {
  const double k = std::tan(std::numbers::pi * cutoff_hz / rate_hz);
  const double norm = 1.0 / (1.0 + std::numbers::sqrt2 * k + k * k);
  Butterworth2 f;
  f.b0 = k * k * norm;
  f.b1 = 2.0 * f.b0;
  f.b2 = f.b0;
  f.a1 = 2.0 * (k * k - 1.0) * norm;
  f.a2 = (1.0 - std::numbers::sqrt2 * k + k * k) * norm;
  return f;
}

namespace {

// One pass in place, its state started as if the signal had always been at its first value
// (the filter's gain at 0 Hz is 1, so a constant passes unchanged).
void pass(const Butterworth2& f, std::span<double> x) {
  double x1 = x[0], x2 = x[0], y1 = x[0], y2 = x[0];
  for (double& v : x) {
    const double y = f.b0 * v + f.b1 * x1 + f.b2 * x2 - f.a1 * y1 - f.a2 * y2;
    x2 = x1, x1 = v, y2 = y1, y1 = y;
    v = y;
  }
}

}  // namespace

void filtfilt(const Butterworth2& f, std::span<double> x) {
  const std::size_t n = x.size(), pad = kFiltfiltPad;
  if (n <= pad) return;
  // Odd reflection about each end: the run's slope carries on past it.
  std::vector<double> ext(n + 2 * pad);
  for (std::size_t k = 0; k < pad; ++k) {
    ext[k] = 2.0 * x[0] - x[pad - k];
    ext[n + pad + k] = 2.0 * x[n - 1] - x[n - 2 - k];
  }
  std::copy(x.begin(), x.end(), ext.begin() + static_cast<std::ptrdiff_t>(pad));
  pass(f, ext);
  std::reverse(ext.begin(), ext.end());
  pass(f, ext);
  std::reverse(ext.begin(), ext.end());
  std::copy_n(ext.begin() + static_cast<std::ptrdiff_t>(pad), n, x.begin());
}

void filtfilt_trial(io::MarkerTrial& trial, double cutoff_hz) {
  if (!(cutoff_hz > 0.0) || !(cutoff_hz < trial.rate_hz / 2.0))
    throw std::invalid_argument("filter cutoff " + std::to_string(cutoff_hz) +
                                " Hz: give one above 0 and below half the trial's rate (" +
                                std::to_string(trial.rate_hz / 2.0) + " Hz)");
  const Butterworth2 f = Butterworth2::low_pass(cutoff_hz, trial.rate_hz);
  const std::size_t frames = trial.frames();
  std::vector<double> run;
  for (std::size_t m = 0; m < trial.markers(); ++m) {
    std::size_t first = 0;
    while (first < frames) {
      if (!trial.at(first, m).allFinite()) {
        ++first;
        continue;
      }
      std::size_t end = first;
      while (end < frames && trial.at(end, m).allFinite()) ++end;
      for (int axis = 0; axis < 3; ++axis) {
        run.resize(end - first);
        for (std::size_t k = first; k < end; ++k) run[k - first] = trial.at(k, m)[axis];
        filtfilt(f, run);
        for (std::size_t k = first; k < end; ++k)
          trial.positions_m[k * trial.markers() + m][axis] = run[k - first];
      }
      first = end;
    }
  }
}

}  // namespace fabrik
