/// @file
/// Joint angles: the Cardan decomposition R = Rz(a_z) Rx(a_x) Ry(a_y) of one
/// anatomical frame relative to another (the ISB joint coordinate system), the
/// projection of a rotation onto a joint's allowed range, and the model's
/// named coordinates. Allocation-free; radians throughout.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <span>

#include "model.hpp"
#include "posture.hpp"

namespace fabrik {

/// (a_z, a_x, a_y) with R = Rz(a_z) Rx(a_x) Ry(a_y); a_x in [-pi/2, pi/2].
Eigen::Vector3d cardan_zxy(const Eigen::Matrix3d& r);
/// The rotation Rz(a_z) Rx(a_x) Ry(a_y) of angles (a_z, a_x, a_y), radians: cardan_zxy's inverse.
Eigen::Matrix3d rotation_zxy(const Eigen::Vector3d& angles_rad);

/// True when `s` names one of the model's segments and the posture has one pose per segment:
/// what the functions below that take a segment index check (in release builds too).
inline bool has_segment(const Model& model, const Posture& posture, int s) {
  return s >= 0 && static_cast<std::size_t>(s) < model.segments.size() &&
         posture.segments.size() == model.segments.size();
}

/// World rotation of a segment's anatomical frame; all NaN when !has_segment.
Eigen::Matrix3d anatomical_world(const Model& model, const Posture& posture, int s);

/// The rotation of segment s's anatomical frame relative to segment
/// `reference`'s (-1: the world); all NaN when either index is not the model's.
Eigen::Matrix3d relative_anatomical(const Model& model, const Posture& posture, int s,
                                    int reference);
/// The Cardan angles (a_z, a_x, a_y), radians, of segment s's base joint: its anatomical
/// frame relative to its parent's (the root's: relative to the world). All NaN when
/// !has_segment.
Eigen::Vector3d joint_angles_rad(const Model& model, const Posture& posture, int s);

/// `angle` clamped to [lo, hi] (radians, lo <= hi within [-pi, pi]). When it is
/// outside, the bound it left through is taken: the one on the shorter arc from
/// `previous` (an angle inside the range) to `angle`; without a previous angle
/// inside the range, the nearer bound. This keeps a limit from snapping to the
/// other side of a wide forbidden arc when the pull comes from behind.
double clamp_angle(double angle, double previous, double lo, double hi);

/// True when the angles lie within the joint's ranges, to `tolerance_rad`.
bool within_limits(const JointLimits& joint, const Eigen::Vector3d& angles_rad,
                   double tolerance_rad);

/// Turns segment s, if its base joint is out of range, to the nearest allowed
/// orientation relative to its parent (each Cardan angle clamped; angles the
/// joint type holds set to their rest values). `previous` is the segment's world
/// rotation before its latest update (for clamp_angle). Returns true if it turned;
/// false, the posture untouched, when !has_segment.
bool enforce_joint_limits(const Model& model, int s, const Eigen::Quaterniond& previous,
                          Posture& posture);

/// The joint angles within the joint's ranges that best turn a segment's
/// vectors onto desired ones: maximise <E(angles), b> (Frobenius), with
/// E = Rz(a_z) Rx(a_x) Ry(a_y) and b = sum_k w_k d_k v_k^T pairing desired
/// vectors d_k (parent joint frame) with the segment's vectors v_k (its own
/// joint frame). Exact coordinate ascent: each angle in turn is the maximum
/// of a sinusoid clamped to its range (clamp_angle, from `start`), `sweeps`
/// times. The result never leaves the ranges; held angles keep their value.
Eigen::Vector3d fit_joint_angles(const Eigen::Matrix3d& b, const JointLimits& joint,
                                 const Eigen::Vector3d& start_rad, int sweeps);

/// Every coordinate of the model (Model::coordinates) at this posture:
/// rotations in radians, translations in metres. Those relative to the world
/// are in the reference frame of Model::lab_axes (OpenSim's ground). Rotations
/// are the Cardan angles' principal values; see unwrap_coordinates. False, and nothing
/// written, when `out` has not one entry per coordinate or the posture one pose per segment.
bool coordinate_values(const Model& model, const Posture& posture, std::span<double> out);

/// Each rotation in `out` moved by whole turns to the value nearest its
/// `previous` one (translations untouched; a NaN previous value leaves it): continuous
/// coordinates over frames, as OpenSim's, which never wrap at +-180 deg. False, and nothing
/// changed, when either span has not one entry per coordinate.
bool unwrap_coordinates(const Model& model, std::span<const double> previous,
                        std::span<double> out);

}  // namespace fabrik
