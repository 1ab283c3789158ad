// Smooth synthetic motion of any model, for benchmarks, tests and the demo:
// every joint swings sinusoidally about its three axes with seeded amplitudes
// and phases (a joint with limits only about the axes it lets move, within
// its ranges), and the root travels and turns slowly. Marker positions can be
// taken with seeded Gaussian noise. Solver types only: no I/O.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <random>
#include <span>
#include <vector>

#include "solver/model.hpp"
#include "solver/posture.hpp"

namespace fabrik {

struct MotionSettings {
  unsigned seed = 1;
  double frequency_hz = 0.9;   // about a gait cycle
  double max_swing_rad = 0.6;  // per-axis amplitude limit of a joint
  double root_travel_m = 0.5;  // root moves back and forth this far
  double root_turn_rad = 0.5;  // and turns this much about the vertical (Y)
  bool move_root = true;
};

class SyntheticMotion {
 public:
  SyntheticMotion(const Model& model, MotionSettings settings);

  // The exact posture at time t (forward kinematics from the rest posture).
  void posture_at(double t_s, Posture& posture);
  // Positions of `points` on `posture`, with isotropic Gaussian noise.
  void sample(const Posture& posture, std::span<const int> points, double noise_m,
              std::span<Eigen::Vector3d> out_world_m);

 private:
  Eigen::Quaterniond limited_rotation(const Segment& seg, const Segment& parent,
                                      const Eigen::Vector3d& amplitude_rad,
                                      const Eigen::Vector3d& phase_rad, double wt) const;

  const Model& model_;
  MotionSettings settings_;
  std::vector<Eigen::Vector3d> amplitude_rad_, phase_rad_;
  std::vector<Eigen::Quaterniond> q_local_;
  std::mt19937_64 rng_;
};

}  // namespace fabrik
