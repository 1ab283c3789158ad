// The solver's inner step for a segment with a limited joint, without
// trigonometry: every angle is carried as its cosine and sine (a Turn), a
// range as the turns of its bounds, and each coordinate-ascent step as the
// normalised peak of a sinusoid, clamped by cross products. The same maths
// as fit_joint_angles (joint_angles.hpp), which the tests compare it with.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cmath>

#include "model.hpp"

namespace fabrik {

// An angle t as (cos t, sin t).
struct Turn {
  double c = 1.0, s = 0.0;
};

using Turns = std::array<Turn, 3>;  // a_z, a_x, a_y as in JointLimits

// A joint's ranges as turns, precomputed once.
struct JointArcs {
  explicit JointArcs(const JointLimits& joint);
  std::array<Turn, 3> lo, hi, rest;
  std::array<bool, 3> held;  // the type holds this angle at rest
  std::array<bool, 3> wide;  // the range spans more than half a turn
  // True if `t` lies within range k (to rounding).
  bool inside(int k, const Turn& t) const {
    // A range up to half a turn: counter-clockwise of lo and clockwise of hi.
    // A wider one: anything not strictly inside the (narrower) rest of the circle.
    if (!wide[k]) return cross(lo[k], t) >= -kInside && cross(t, hi[k]) >= -kInside;
    return !(cross(hi[k], t) > kInside && cross(t, lo[k]) > kInside);
  }
  // `t` if inside range k, else the bound it left through coming from
  // `previous` (inside), or the nearer bound (see clamp_angle).
  Turn clamp(int k, const Turn& t, const Turn& previous) const {
    if (held[k]) return rest[k];
    if (inside(k, t)) return t;
    if (inside(k, previous)) return cross(previous, t) > 0.0 ? hi[k] : lo[k];
    return dot(t, lo[k]) >= dot(t, hi[k]) ? lo[k] : hi[k];
  }
  // True if `t` is exactly one of range k's bounds, as clamp leaves an angle that left it.
  bool at_bound(int k, const Turn& t) const { return same(t, lo[k]) || same(t, hi[k]); }
  static double cross(const Turn& a, const Turn& b) { return a.c * b.s - a.s * b.c; }
  static double dot(const Turn& a, const Turn& b) { return a.c * b.c + a.s * b.s; }

 private:
  // Rounding allowance for the range tests, in sine units (radians near 0).
  static constexpr double kInside = 1e-12;
  static bool same(const Turn& a, const Turn& b) { return a.c == b.c && a.s == b.s; }
};

// The Cardan turns of r = Rz Rx Ry (a_x's cosine is taken >= 0).
Turns turns_zxy(const Eigen::Matrix3d& r);
Eigen::Matrix3d rotation_zxy(const Turns& t);

// The peak of c cos(t) + s sin(t) as a turn; `fallback` when it has none.
inline Turn peak_turn(double c, double s, const Turn& fallback) {
  const double n2 = c * c + s * s;
  if (n2 < 1e-30) return fallback;
  // sqrt(n2) / n2: the root and the division do not wait for each other.
  const double inv = std::sqrt(n2) * (1.0 / n2);
  return {c * inv, s * inv};
}
// cos(t/2) and sin(t/2) of a turn t in (-pi, pi].
void half_turn(const Turn& t, double& c, double& s);
// The angle of a rotation's twist about unit axis u, as a turn.
Turn twist_turn(const Eigen::Quaterniond& q, const Eigen::Vector3d& u);

// The unit quaternion of a turn t about unit axis u.
Eigen::Quaterniond quaternion_about(const Turn& t, const Eigen::Vector3d& u);

// The unit quaternion of E = Rz Rx Ry, from the turns' half angles.
Eigen::Quaterniond quaternion_zxy(const Turns& t);

// Coordinate ascent of <E(turns), b> within the ranges, from `t` (brought
// into the ranges first; held angles set to rest), `sweeps` times.
void fit_joint_turns(const Eigen::Matrix3d& b, const JointArcs& arcs, Turns& t, int sweeps);

}  // namespace fabrik
