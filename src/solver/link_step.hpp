// The FABRIK step of a link (a segment one point alone drives, fabrik_solver.hpp): its moving
// end goes onto the line from its fixed end towards where the moving end should be, at the
// link's length. Along a run of links (a chain, an arm) every step starts where the step
// before it ended, so a pass is one long chain of dependent operations: its length per step,
// not the work, sets the time (on chains of 100-200 links the forward and backward passes
// ran at the latency of ~48 cycles a step).
//
// A chained step takes its squared distance from the previous step's instead of waiting for
// that step's result: with the previous step p -> p' = p + f u (u its direction's vector,
// f = len_p / |u|) and this step's far point t, w = t - p is known before f, and
//   |t - p'|^2 = |w|^2 - 2 f (w . u) + f^2 |u|^2 (= |w|^2 + len_p^2 - 2 f (w . u)),
// one multiply and one subtract after f, where the direct |t - p'|^2 needs p' first (a
// multiply and an add), then a subtract and a dot product. The square root and the
// division, the rest of the step, are unchanged. Exact algebraically; it cancels when the
// result is small against |w|^2 + len_p^2, so below 1e-4 of that the step takes the direct
// sum (relative error then < 1e-11).
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace fabrik {

struct LinkStep {
  int segment = -1;               // whose step this was (-1: none a next step may chain on)
  double fx = 0, fy = 0, fz = 0;  // where it started (its fixed end), world, m
  double ux = 0, uy = 0, uz = 0;  // towards its far point: far - start, m
  double g = 0;                   // 1 / |u|, 1/m
  double u_sq = 0, inv_sq = 0;    // |u|^2 (m^2), and 1 / the squared length it used (1/m^2)
  double len_m = 0;               // the link's length

  // The step of a link of length len_m from from_m towards to_m; `chained`: from_m is the
  // end of this object's last step (see above), and not read. Sets `end_m` and returns
  // true, or returns false (end_m untouched) when to_m sits on from_m: no direction.
  bool step(const Eigen::Vector3d& from_m, const Eigen::Vector3d& to_m, double link_len_m,
            bool chained, Eigen::Vector3d& end_m) {
    double vx, vy, vz, dist_sq, sx, sy, sz;
    if (chained) {
      // This step starts where the last one ended, fx + f u as it computed it (so from_m to
      // the bit), in registers: the next step's dot products need it early.
      const double f = len_m * g;
      sx = fx + f * ux;
      sy = fy + f * uy;
      sz = fz + f * uz;
      const double wx = to_m.x() - fx, wy = to_m.y() - fy, wz = to_m.z() - fz;
      const double w_sq = wx * wx + wy * wy + wz * wz;
      const double two_len_m = 2.0 * len_m;
      const double wu2 = wx * (two_len_m * ux) + wy * (two_len_m * uy) + wz * (two_len_m * uz);
      // f^2 |u|^2 as it stands: len^2 |u|^2 / (the squared length the last step used), not
      // len^2, so that one step's rounding does not carry into the next (along a run that
      // folds up, where each step is shorter than its link, it would grow step by step).
      const double base_sq = w_sq + (len_m * len_m * u_sq) * inv_sq;
      dist_sq = base_sq - g * wu2;
      vx = wx - f * ux;
      vy = wy - f * uy;
      vz = wz - f * uz;
      if (!(dist_sq > 1e-4 * base_sq)) dist_sq = vx * vx + vy * vy + vz * vz;
    } else {
      sx = from_m.x();
      sy = from_m.y();
      sz = from_m.z();
      vx = to_m.x() - sx;
      vy = to_m.y() - sy;
      vz = to_m.z() - sz;
      dist_sq = vx * vx + vy * vy + vz * vz;
    }
    if (!(dist_sq > 1e-24)) {
      segment = -1;
      return false;
    }
    // The square root and the division do not wait for each other.
    inv_sq = 1.0 / dist_sq;
    g = std::sqrt(dist_sq) * inv_sq;
    const double f = link_len_m * g;
    fx = sx;
    fy = sy;
    fz = sz;
    ux = vx;
    uy = vy;
    uz = vz;
    u_sq = vx * vx + vy * vy + vz * vz;
    len_m = link_len_m;
    end_m = Eigen::Vector3d(fx + f * vx, fy + f * vy, fz + f * vz);
    return true;
  }
};

}  // namespace fabrik
