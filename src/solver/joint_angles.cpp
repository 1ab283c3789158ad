#include "joint_angles.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace fabrik {

namespace {

// Angle in (-pi, pi].
double wrap(double a) {
  a = std::remainder(a, 2.0 * std::numbers::pi);
  return a <= -std::numbers::pi ? a + 2.0 * std::numbers::pi : a;
}

// Angles this close to a range count as inside it: a hinge's held angles are
// set exactly, up to rounding.
constexpr double kInsideRad = 1e-10;

bool in_range(double a, double lo, double hi) {
  return a >= lo - kInsideRad && a <= hi + kInsideRad;
}

Eigen::Quaterniond quaternion_zxy(const Eigen::Vector3d& a) {
  const double cz = std::cos(0.5 * a[0]), sz = std::sin(0.5 * a[0]);
  const double cx = std::cos(0.5 * a[1]), sx = std::sin(0.5 * a[1]);
  const double cy = std::cos(0.5 * a[2]), sy = std::sin(0.5 * a[2]);
  // qz * qx * qy
  const Eigen::Quaterniond zx(cz * cx, cz * sx, sz * sx, sz * cx);
  return zx * Eigen::Quaterniond(cy, 0.0, sy, 0.0);
}

// The entries of a rotation matrix that its Cardan angles read: Rz(a) Rx(b) Ry(c) has
// r(2,1) = sin b, r(0,1) = -sin a cos b, r(1,1) = cos a cos b, r(2,0) = -cos b sin c,
// r(2,2) = cos b cos c.
struct CardanEntries {
  double r01, r11, r21, r20, r22;

  static CardanEntries of(const Eigen::Matrix3d& r) {
    return {r(0, 1), r(1, 1), r(2, 1), r(2, 0), r(2, 2)};
  }
  // Of a unit quaternion's matrix (the terms of Eigen's toRotationMatrix), without the rest.
  static CardanEntries of(const Eigen::Quaterniond& q) {
    const double w = q.w(), x = q.x(), y = q.y(), z = q.z();
    return {2.0 * (x * y) - 2.0 * (w * z), 1.0 - (2.0 * (x * x) + 2.0 * (z * z)),
            2.0 * (y * z) + 2.0 * (w * x), 2.0 * (x * z) - 2.0 * (w * y),
            1.0 - (2.0 * (x * x) + 2.0 * (y * y))};
  }
  // Angle k of (a_z, a_x, a_y).
  double angle(int k) const {
    if (k == 0) return std::atan2(-r01, r11);
    if (k == 1) return std::asin(std::clamp(r21, -1.0, 1.0));
    return std::atan2(-r20, r22);
  }
};

}  // namespace

Eigen::Vector3d cardan_zxy(const Eigen::Matrix3d& r) {
  const CardanEntries e = CardanEntries::of(r);
  return {e.angle(0), e.angle(1), e.angle(2)};
}

Eigen::Matrix3d rotation_zxy(const Eigen::Vector3d& a) {
  return (Eigen::AngleAxisd(a[0], Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(a[1], Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(a[2], Eigen::Vector3d::UnitY()))
      .toRotationMatrix();
}

Eigen::Matrix3d anatomical_world(const Model& model, const Posture& posture, int s) {
  if (!has_segment(model, posture, s))
    return Eigen::Matrix3d::Constant(std::numeric_limits<double>::quiet_NaN());
  return posture.segments[s].r_world * model.segments[s].q_anatomical.toRotationMatrix();
}

Eigen::Matrix3d relative_anatomical(const Model& model, const Posture& posture, int s,
                                    int reference) {
  const Eigen::Matrix3d child = anatomical_world(model, posture, s);
  if (reference == -1) return child;
  return anatomical_world(model, posture, reference).transpose() * child;
}

Eigen::Vector3d joint_angles_rad(const Model& model, const Posture& posture, int s) {
  if (!has_segment(model, posture, s))
    return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  return cardan_zxy(relative_anatomical(model, posture, s, model.segments[s].parent));
}

double clamp_angle(double angle, double previous, double lo, double hi) {
  if (in_range(angle, lo, hi)) return angle;
  if (in_range(previous, lo, hi)) return wrap(angle - previous) > 0.0 ? hi : lo;
  return std::abs(wrap(angle - lo)) <= std::abs(wrap(angle - hi)) ? lo : hi;
}

bool within_limits(const JointLimits& joint, const Eigen::Vector3d& angles_rad,
                   double tolerance_rad) {
  if (!joint.limited()) return true;
  for (int k = 0; k < 3; ++k) {
    const double a = angles_rad[k];
    // Distance outside [lo, hi] on the circle (a_x never wraps).
    const double below = k == 1 ? joint.min_rad[k] - a : wrap(joint.min_rad[k] - a);
    const double above = k == 1 ? a - joint.max_rad[k] : wrap(a - joint.max_rad[k]);
    if (!in_range(a, joint.min_rad[k] - tolerance_rad, joint.max_rad[k] + tolerance_rad) &&
        std::min(std::abs(below), std::abs(above)) > tolerance_rad)
      return false;
  }
  return true;
}

bool enforce_joint_limits(const Model& model, int s, const Eigen::Quaterniond& previous,
                          Posture& posture) {
  if (!has_segment(model, posture, s)) return false;
  const Segment& seg = model.segments[s];
  const JointLimits& joint = seg.joint;
  if (!joint.limited() || seg.parent < 0) return false;
  SegmentPose& pose = posture.segments[s];
  const Eigen::Quaterniond& q_parent = posture.segments[seg.parent].q_world;
  if (joint.type == JointType::fixed) {
    // At rest every frame is the world's: a fixed joint keeps the parent's rotation.
    pose.set_unit_rotation(q_parent);
    return true;
  }
  const Eigen::Quaterniond& a_parent = model.segments[seg.parent].q_anatomical;
  const Eigen::Quaterniond& a_child = seg.q_anatomical;
  const Eigen::Quaterniond to_joint = a_parent.conjugate() * q_parent.conjugate();
  const Eigen::Vector3d angles =
      cardan_zxy((to_joint * pose.q_world * a_child).toRotationMatrix());
  bool inside = true;
  for (int k = 0; k < 3; ++k)
    inside = inside && in_range(angles[k], joint.min_rad[k], joint.max_rad[k]);
  if (inside) return false;
  const Eigen::Vector3d before = cardan_zxy((to_joint * previous * a_child).toRotationMatrix());
  Eigen::Vector3d allowed;
  for (int k = 0; k < 3; ++k)
    allowed[k] = clamp_angle(angles[k], before[k], joint.min_rad[k], joint.max_rad[k]);
  pose.set_rotation(q_parent * a_parent * quaternion_zxy(allowed) * a_child.conjugate());
  return true;
}

namespace {

Eigen::Matrix3d rot_z(double t) {
  const double c = std::cos(t), s = std::sin(t);
  Eigen::Matrix3d r;
  r << c, -s, 0, s, c, 0, 0, 0, 1;
  return r;
}
Eigen::Matrix3d rot_x(double t) {
  const double c = std::cos(t), s = std::sin(t);
  Eigen::Matrix3d r;
  r << 1, 0, 0, 0, c, -s, 0, s, c;
  return r;
}
Eigen::Matrix3d rot_y(double t) {
  const double c = std::cos(t), s = std::sin(t);
  Eigen::Matrix3d r;
  r << c, 0, s, 0, 1, 0, -s, 0, c;
  return r;
}

// The angle in [lo, hi] that maximises c cos(t) + s sin(t), starting from `now`.
double best_angle(double c, double s, double now, double lo, double hi) {
  if (hi - lo <= 0.0) return lo;  // held
  if (c * c + s * s < 1e-30) return std::clamp(now, lo, hi);
  return clamp_angle(std::atan2(s, c), now, lo, hi);
}

}  // namespace

Eigen::Vector3d fit_joint_angles(const Eigen::Matrix3d& b, const JointLimits& joint,
                                 const Eigen::Vector3d& start_rad, int sweeps) {
  Eigen::Vector3d a = start_rad;
  for (int k = 0; k < 3; ++k)  // a start outside the ranges is brought in first
    a[k] = clamp_angle(a[k], a[k], joint.min_rad[k], joint.max_rad[k]);
  Eigen::Matrix3d rz = rot_z(a[0]), rx = rot_x(a[1]), ry = rot_y(a[2]);
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    // a_z: <Rz(t) M, b> = <Rz(t), b M^T>, M = Rx Ry.
    {
      const Eigen::Matrix3d c = b * (rx * ry).transpose();
      a[0] = best_angle(c(0, 0) + c(1, 1), c(1, 0) - c(0, 1), a[0], joint.min_rad[0],
                        joint.max_rad[0]);
      rz = rot_z(a[0]);
    }
    // a_x: <Rz Rx(t) Ry, b> = <Rx(t), Rz^T b Ry^T>.
    {
      const Eigen::Matrix3d d = rz.transpose() * b * ry.transpose();
      a[1] = best_angle(d(1, 1) + d(2, 2), d(2, 1) - d(1, 2), a[1], joint.min_rad[1],
                        joint.max_rad[1]);
      rx = rot_x(a[1]);
    }
    // a_y: <M Ry(t), b> = <Ry(t), M^T b>, M = Rz Rx.
    {
      const Eigen::Matrix3d g = (rz * rx).transpose() * b;
      a[2] = best_angle(g(0, 0) + g(2, 2), g(0, 2) - g(2, 0), a[2], joint.min_rad[2],
                        joint.max_rad[2]);
      ry = rot_y(a[2]);
    }
  }
  return a;
}

bool coordinate_values(const Model& model, const Posture& posture, std::span<double> out) {
  if (out.size() != model.coordinates.size() || posture.segments.size() != model.segments.size())
    return false;
  // World-relative coordinates are OpenSim's, relative to its ground: the
  // lab's axes turned onto X forward, Y up. A lab that is already so is
  // left alone: its values stay bit for bit what they were.
  const bool turned = !(model.lab_axes == LabAxes{});
  const Eigen::Matrix3d r_reference_lab = model.lab_axes.r_reference_lab();
  // Each coordinate computes its own angle only (a knee's one of three), from the
  // relative rotation as a quaternion: about half the time of the matrices' way.
  int cached_segment = -2, cached_reference = -2;
  CardanEntries entries{};
  for (std::size_t i = 0; i < model.coordinates.size(); ++i) {
    const Coordinate& c = model.coordinates[i];
    double raw = 0.0;
    if (c.kind == CoordinateKind::rotation) {
      if (c.segment != cached_segment || c.relative_to != cached_reference) {
        const Eigen::Quaterniond child =
            posture.segments[c.segment].q_world * model.segments[c.segment].q_anatomical;
        if (c.relative_to >= 0) {
          const Eigen::Quaterniond reference = posture.segments[c.relative_to].q_world *
                                               model.segments[c.relative_to].q_anatomical;
          entries = CardanEntries::of(Eigen::Quaterniond(reference.conjugate() * child));
        } else if (turned) {  // the lab's axes turned exactly (a signed permutation)
          entries = CardanEntries::of(Eigen::Matrix3d(r_reference_lab * child.toRotationMatrix()));
        } else {
          entries = CardanEntries::of(child);
        }
        cached_segment = c.segment;
        cached_reference = c.relative_to;
      }
      raw = entries.angle(c.angle);
    } else {
      const Eigen::Vector3d p_lab_m = posture.point_world_m(model, c.point);
      raw = (turned ? Eigen::Vector3d(r_reference_lab * p_lab_m) : p_lab_m)[c.axis];
    }
    out[i] = c.sign * (raw + c.offset);
  }
  return true;
}

bool unwrap_coordinates(const Model& model, std::span<const double> previous,
                        std::span<double> out) {
  if (previous.size() != model.coordinates.size() || out.size() != model.coordinates.size())
    return false;
  constexpr double kTurn = 2.0 * std::numbers::pi;
  for (std::size_t i = 0; i < model.coordinates.size(); ++i) {
    const Coordinate& c = model.coordinates[i];
    if (c.kind != CoordinateKind::rotation || !std::isfinite(previous[i])) continue;
    // value = sign * (raw + offset): a whole turn of raw is sign turns of the value.
    const double turn = c.sign * kTurn;
    out[i] += turn * std::round((previous[i] - out[i]) / turn);
  }
  return true;
}

}  // namespace fabrik
