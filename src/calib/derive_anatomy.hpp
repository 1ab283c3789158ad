// Anatomical frames and named coordinates for a template that names no
// coordinates, derived from its segment tree, its names and the static
// posture (docs/calibration.md, "Angles for any template"). The rules, in short:
// * the body's up is where the root's limbs point proximally (and its trunk
//   distally); its right is the mean of every left-to-right pair of markers or
//   points (RASI/LASI, r_hip/l_hip, R.Knee/L.Knee);
// * the root's frame: y up, z right (made orthogonal), x = y cross z;
// * another segment's y runs from its distal joint (its child's base, or its
//   end sites, or its markers' centroid) to its base on a limb and the other
//   way on the trunk and head; z is the line through the two markers whose
//   midpoint is its distal joint (epicondyles, malleoli, styloids) or else
//   its parent's z, made orthogonal; feet and toes take the frame of the
//   segment above (ISB's calcaneus frame is the tibia's at neutral);
// * coordinates: the root's three angles relative to the lab and its base's
//   position, then each joint's Cardan angles relative to its parent, named
//   as OpenSim names them where the segment name is recognised, else
//   <segment>_flexion/_adduction/_rotation.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "calib_template.hpp"

namespace fabrik::calib {

struct DerivedAnatomy {
  // Per template segment: the derived anatomical frame (columns x, y, z in
  // the world at the static posture), or none (the template gives one, or
  // none could be derived).
  std::vector<std::optional<Eigen::Matrix3d>> frames;
  // fabrikd-model/1 "coordinates"; null when nothing was derived.
  nlohmann::ordered_json coordinates;
  // What was derived and from what, one line per segment, for calibrate's
  // report; or why nothing could be, with a recipe that works.
  std::vector<std::string> report;
  bool failed = false;
};

// Nothing is derived when the template names coordinates (it is then
// complete as written). `point_world_m` follows CalibTemplate::points,
// `marker_mean_m` CalibTemplate::markers (NaN where the static has none);
// `given_frames` holds the template's own frames per segment.
DerivedAnatomy derive_anatomy(const CalibTemplate& tmpl, std::span<const Eigen::Vector3d> point_world_m,
                              std::span<const Eigen::Vector3d> marker_mean_m,
                              std::span<const std::optional<Eigen::Matrix3d>> given_frames);

}  // namespace fabrik::calib
