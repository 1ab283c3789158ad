// Geometry shared by the offline and live donor-marker fills: the frame
// spanned by three marker positions (origin a, x towards b, z normal to the
// triangle), and the spread of a distance over frames, which ranks donors.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace fabrik {

// False (r untouched) when the triangle is flatter than min_sine (the sine of
// its angle at a) or degenerate.
inline bool triad(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                  double min_sine, Eigen::Matrix3d& r) {
  const Eigen::Vector3d ab = b - a, ac = c - a;
  const double lab = ab.norm(), lac = ac.norm();
  if (!(lab > 1e-9) || !(lac > 1e-9)) return false;
  const Eigen::Vector3d normal = ab.cross(ac);
  const double sine = normal.norm() / (lab * lac);
  if (!(sine >= min_sine) || !(sine > 1e-12)) return false;
  r.col(0) = ab / lab;
  r.col(2) = normal / (sine * lab * lac);
  r.col(1) = r.col(2).cross(r.col(0));
  return true;
}

// Standard deviation of a distance over the frames added (metres).
struct DistanceSpread {
  double sum_m = 0.0, sum_sq_m2 = 0.0;
  int frames = 0;
  void add(double d_m) {
    sum_m += d_m;
    sum_sq_m2 += d_m * d_m;
    ++frames;
  }
  double spread_m() const {
    const double mean_m = sum_m / frames;
    return std::sqrt(std::max(0.0, sum_sq_m2 / frames - mean_m * mean_m));
  }
};

}  // namespace fabrik
