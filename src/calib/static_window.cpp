#include "static_window.hpp"

namespace fabrik::calib {

WindowMotion window_motion(const io::MarkerTrial& trial, const std::vector<int>& columns,
                           std::size_t first, std::size_t count) {
  WindowMotion w;
  for (const int c : columns) {
    if (c < 0) continue;
    const auto col = static_cast<std::size_t>(c);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    std::size_t n = 0;
    for (std::size_t f = first; f < first + count; ++f) {
      const Eigen::Vector3d& p = trial.at(f, col);
      if (p.allFinite()) sum += p, ++n;
    }
    w.missing += count - n;
    if (n == 0) continue;
    const Eigen::Vector3d mean = sum / static_cast<double>(n);
    for (std::size_t f = first; f < first + count; ++f) {
      const Eigen::Vector3d& p = trial.at(f, col);
      if (!p.allFinite()) continue;
      const double d_m = (p - mean).norm();
      if (w.column < 0 || d_m > w.motion_m) w.motion_m = d_m, w.column = c;
    }
  }
  return w;
}

std::size_t stillest_window(const io::MarkerTrial& trial, const std::vector<int>& columns,
                            std::size_t count) {
  std::size_t best = 0;
  WindowMotion best_w;
  for (std::size_t first = 0; first + count <= trial.frames(); ++first) {
    const WindowMotion w = window_motion(trial, columns, first, count);
    if (first == 0 || w.missing < best_w.missing ||
        (w.missing == best_w.missing && w.motion_m < best_w.motion_m))
      best = first, best_w = w;
  }
  return best;
}

}  // namespace fabrik::calib
