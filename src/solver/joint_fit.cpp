#include "joint_fit.hpp"

#include <algorithm>
#include <cmath>

namespace fabrik {

namespace {

Turn turn_of(double angle_rad) {
  return {std::cos(angle_rad), std::sin(angle_rad)};
}

}  // namespace

JointArcs::JointArcs(const JointLimits& joint) {
  for (int k = 0; k < 3; ++k) {
    lo[k] = turn_of(joint.min_rad[k]);
    hi[k] = turn_of(joint.max_rad[k]);
    rest[k] = turn_of(joint.rest_rad[k]);
    held[k] = joint.max_rad[k] - joint.min_rad[k] <= 0.0;
    wide[k] = joint.max_rad[k] - joint.min_rad[k] > 3.141592653589793;
  }
}

Turns turns_zxy(const Eigen::Matrix3d& r) {
  // Rz(a) Rx(b) Ry(c): r(2,1) = sin b, (r(1,1), -r(0,1)) = cos b (cos a, sin a),
  // (r(2,2), -r(2,0)) = cos b (cos c, sin c).
  Turns t;
  const double sb = std::clamp(r(2, 1), -1.0, 1.0);
  t[1] = {std::sqrt(1.0 - sb * sb), sb};
  t[0] = peak_turn(r(1, 1), -r(0, 1), Turn{});
  t[2] = peak_turn(r(2, 2), -r(2, 0), Turn{});
  return t;
}

Eigen::Matrix3d rotation_zxy(const Turns& t) {
  const double ca = t[0].c, sa = t[0].s, cb = t[1].c, sb = t[1].s, cc = t[2].c, sc = t[2].s;
  Eigen::Matrix3d r;
  r << ca * cc - sa * sb * sc, -sa * cb, ca * sc + sa * sb * cc,  //
      sa * cc + ca * sb * sc, ca * cb, sa * sc - ca * sb * cc,    //
      -cb * sc, sb, cb * cc;
  return r;
}

void half_turn(const Turn& t, double& c, double& s) {
  if (t.c > -0.5) {
    c = std::sqrt(0.5 * (1.0 + t.c));
    s = t.s / (2.0 * c);
  } else {  // near a half turn: from the sine's side
    s = std::copysign(std::sqrt(0.5 * (1.0 - t.c)), t.s);
    c = t.s / (2.0 * s);
  }
}

Turn twist_turn(const Eigen::Quaterniond& q, const Eigen::Vector3d& u) {
  // The twist is (w, (v.u) u) / norm, of angle t with cos(t/2) ~ w, sin(t/2) ~ v.u.
  const double w = q.w(), a = u.dot(q.vec()), n2 = w * w + a * a;
  if (n2 < 1e-30) return Turn{};
  return {(w * w - a * a) / n2, 2.0 * w * a / n2};
}

Eigen::Quaterniond quaternion_about(const Turn& t, const Eigen::Vector3d& u) {
  double c, s;
  half_turn(t, c, s);
  return Eigen::Quaterniond(c, s * u.x(), s * u.y(), s * u.z());
}

Eigen::Quaterniond quaternion_zxy(const Turns& t) {
  double cz, sz, cx, sx, cy, sy;
  half_turn(t[0], cz, sz);
  half_turn(t[1], cx, sx);
  half_turn(t[2], cy, sy);
  // qz qx = (cz cx, cz sx, sz sx, sz cx), then times qy = (cy, 0, sy, 0).
  const double w = cz * cx, x = cz * sx, y = sz * sx, z = sz * cx;
  return Eigen::Quaterniond(w * cy - y * sy, x * cy - z * sy, w * sy + y * cy, z * cy + x * sy);
}

void fit_joint_turns(const Eigen::Matrix3d& b, const JointArcs& arcs, Turns& t, int sweeps) {
  for (int k = 0; k < 3; ++k) t[k] = arcs.clamp(k, t[k], t[k]);
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    if (!arcs.held[0]) {
      // <Rz(a) M, b> with M = Rx Ry: rows m0, m1 of M against rows of b.
      const double cb = t[1].c, sb = t[1].s, cc = t[2].c, sc = t[2].s;
      const double m00 = cc, m01 = 0.0, m02 = sc;
      const double m10 = sb * sc, m11 = cb, m12 = -sb * cc;
      const double d00 = b(0, 0) * m00 + b(0, 1) * m01 + b(0, 2) * m02;
      const double d11 = b(1, 0) * m10 + b(1, 1) * m11 + b(1, 2) * m12;
      const double d10 = b(1, 0) * m00 + b(1, 1) * m01 + b(1, 2) * m02;
      const double d01 = b(0, 0) * m10 + b(0, 1) * m11 + b(0, 2) * m12;
      t[0] = arcs.clamp(0, peak_turn(d00 + d11, d10 - d01, t[0]), t[0]);
    }
    if (!arcs.held[1]) {
      // <Rx(b), D> with D = Rz^T b Ry^T: entries (1,1), (2,2), (2,1), (1,2).
      const double ca = t[0].c, sa = t[0].s, cc = t[2].c, sc = t[2].s;
      // Rows 1 and 2 of Rz^T b: (-sa, ca, 0) b and (0, 0, 1) b.
      const Eigen::Vector3d r1 = -sa * b.row(0).transpose() + ca * b.row(1).transpose();
      const Eigen::Vector3d r2 = b.row(2).transpose();
      // Columns 1 and 2 of Ry^T: (0, 1, 0) and (-sc, 0, cc).
      const double d11 = r1.y(), d21 = r2.y();
      const double d12 = -sc * r1.x() + cc * r1.z(), d22 = -sc * r2.x() + cc * r2.z();
      t[1] = arcs.clamp(1, peak_turn(d11 + d22, d21 - d12, t[1]), t[1]);
    }
    if (!arcs.held[2]) {
      // <Ry(c), G> with G = (Rz Rx)^T b: entries (0,0), (2,2), (0,2), (2,0).
      const double ca = t[0].c, sa = t[0].s, cb = t[1].c, sb = t[1].s;
      // Columns 0 and 2 of Rz Rx: (ca, sa, 0) and (sa sb, -ca sb, cb).
      const Eigen::Vector3d g0 = ca * b.row(0).transpose() + sa * b.row(1).transpose();
      const Eigen::Vector3d g2 =
          sa * sb * b.row(0).transpose() - ca * sb * b.row(1).transpose() + cb * b.row(2).transpose();
      t[2] = arcs.clamp(2, peak_turn(g0.x() + g2.z(), g0.z() - g2.x(), t[2]), t[2]);
    }
  }
}

}  // namespace fabrik
