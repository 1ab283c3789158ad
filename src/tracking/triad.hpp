// The frame spanned by three marker positions: origin a, x towards b, z
// normal to the triangle (the local frame of donor-marker fills).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

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

}  // namespace fabrik
