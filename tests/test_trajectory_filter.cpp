// The offline zero-lag filter (`fabrik solve --filter-hz`): a constant passes unchanged, a
// sine comes out without phase shift, gaps stay gaps and nothing is carried across them.
#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "offline/trajectory_filter.hpp"

using namespace fabrik;

namespace {

// One marker at `rate_hz`, x = f(t); y, z constant.
io::MarkerTrial one_marker(double rate_hz, int frames, double (*x_of_t)(double)) {
  io::MarkerTrial t;
  t.labels = {"RKnee"};
  t.rate_hz = rate_hz;
  for (int k = 0; k < frames; ++k) t.positions_m.emplace_back(x_of_t(k / rate_hz), 0.9, -0.2);
  return t;
}

// Phase of the 1 Hz fundamental of samples [first, end) (radians).
double phase_1hz(const io::MarkerTrial& t, std::size_t first, std::size_t end) {
  double a = 0.0, b = 0.0;
  const double w = 2.0 * std::numbers::pi;
  for (std::size_t k = first; k < end; ++k) {
    const double time = static_cast<double>(k) / t.rate_hz;
    a += t.at(k, 0).x() * std::sin(w * time), b += t.at(k, 0).x() * std::cos(w * time);
  }
  return std::atan2(b, a);
}

}  // namespace

TEST_CASE("filtfilt: a constant passes unchanged, to the last sample", "[filter]") {
  io::MarkerTrial t = one_marker(100.0, 50, [](double) { return 0.37; });
  filtfilt_trial(t, 6.0);
  for (std::size_t k = 0; k < t.frames(); ++k)
    CHECK((t.at(k, 0) - Eigen::Vector3d(0.37, 0.9, -0.2)).norm() < 1e-12);
}

TEST_CASE("filtfilt: a 1 Hz sine with noise comes out without lag, the noise cut", "[filter]") {
  io::MarkerTrial clean = one_marker(100.0, 600, [](double t) {
    return 0.1 * std::sin(2.0 * std::numbers::pi * t);
  });
  io::MarkerTrial noisy = clean;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 0.005);
  for (auto& p : noisy.positions_m) p.x() += noise(rng);
  io::MarkerTrial filtered = noisy;
  filtfilt_trial(filtered, 6.0);
  const double lag_frames =
      (phase_1hz(clean, 100, 500) - phase_1hz(filtered, 100, 500)) / (2.0 * std::numbers::pi) * 100.0;
  double err_noisy = 0.0, err_filtered = 0.0;
  for (std::size_t k = 0; k < clean.frames(); ++k) {
    err_noisy += std::pow(noisy.at(k, 0).x() - clean.at(k, 0).x(), 2);
    err_filtered += std::pow(filtered.at(k, 0).x() - clean.at(k, 0).x(), 2);
  }
  INFO("lag " << lag_frames << " frames; RMS error " << std::sqrt(err_noisy / 600) * 1e3
              << " mm noisy, " << std::sqrt(err_filtered / 600) * 1e3 << " mm filtered");
  CHECK(std::abs(lag_frames) < 0.02);
  CHECK(err_filtered < 0.25 * err_noisy);  // RMS at least halved
}

TEST_CASE("filtfilt: gaps stay gaps, each run filtered on its own", "[filter]") {
  // A constant 0.2 m before the gap and 0.5 m after: were anything carried across, the
  // samples beside the gap would be pulled towards the other level.
  io::MarkerTrial t = one_marker(100.0, 120, [](double time) { return time < 0.6 ? 0.2 : 0.5; });
  for (int k = 55; k < 65; ++k) t.positions_m[k] = Eigen::Vector3d::Constant(NAN);
  t.positions_m[100] = Eigen::Vector3d::Constant(NAN);  // a one-sample gap
  // A run too short to filter: 3 samples between gaps, left as they are.
  for (int k = 20; k < 30; ++k)
    if (k != 24 && k != 25 && k != 26) t.positions_m[k] = Eigen::Vector3d::Constant(NAN);
  t.positions_m[25].x() = 0.3;
  filtfilt_trial(t, 6.0);
  for (std::size_t k = 0; k < t.frames(); ++k) {
    const bool gap = (k >= 20 && k < 30 && k != 24 && k != 25 && k != 26) || (k >= 55 && k < 65) ||
                     k == 100;
    INFO("frame " << k);
    CHECK(t.at(k, 0).allFinite() == !gap);
    if (gap) continue;
    const double level = k == 25 ? 0.3 : k < 55 ? 0.2 : 0.5;
    CHECK(t.at(k, 0).x() == Approx(level).margin(1e-9));
  }
}

TEST_CASE("filtfilt: a cutoff at or above half the rate is refused", "[filter]") {
  io::MarkerTrial t = one_marker(100.0, 50, [](double) { return 0.0; });
  CHECK_THROWS_AS(filtfilt_trial(t, 50.0), std::invalid_argument);
  CHECK_THROWS_AS(filtfilt_trial(t, 0.0), std::invalid_argument);
}
