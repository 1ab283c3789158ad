// Random vectors and rotations drawn in a fixed order. The arguments of one
// call are evaluated in an unspecified order (GCC goes right to left, Clang
// left to right), so `Vector3d(g(rng), g(rng), g(rng))` gives a different
// vector under each compiler: draw into locals, one statement each.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace fabrik {

// (x, y, z), drawn in that order.
template <class Distribution, class Engine>
Eigen::Vector3d draw_vector3(Distribution& d, Engine& rng) {
  const double x = d(rng);
  const double y = d(rng);
  const double z = d(rng);
  return {x, y, z};
}

// A uniformly random rotation: a normalised quaternion of four Gaussian
// draws (w, x, y, z in that order). `gaussian` must be standard normal.
template <class Distribution, class Engine>
Eigen::Quaterniond draw_rotation(Distribution& gaussian, Engine& rng) {
  const double w = gaussian(rng);
  const Eigen::Vector3d v = draw_vector3(gaussian, rng);
  return Eigen::Quaterniond(w, v.x(), v.y(), v.z()).normalized();
}

}  // namespace fabrik
