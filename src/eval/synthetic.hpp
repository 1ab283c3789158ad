// `fabrik eval synthetic`: joint centres against the truth on synthetic
// motion with marker noise.
#pragma once

#include <cstddef>
#include <vector>

#include "config/daemon_config.hpp"

namespace fabrik::eval {

struct SyntheticOptions {
  std::vector<double> noise_mm{0.0, 1.0, 3.0};  // per axis, Gaussian
  double seconds = 10.0;
  double rate_hz = 100.0;
  unsigned seed = 1;
};

struct SyntheticRow {
  double noise_mm = 0.0;
  std::size_t frames = 0;
  double joint_rms_m = 0.0, joint_p99_m = 0.0, joint_max_m = 0.0;  // joints vs truth
  double marker_rms_mean_m = 0.0;
};

std::vector<SyntheticRow> eval_synthetic(const DaemonConfig& config,
                                         const SyntheticOptions& options = {});

}  // namespace fabrik::eval
