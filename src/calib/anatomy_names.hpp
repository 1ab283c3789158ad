// What a segment's or marker's name says about the body, for templates that
// leave out frames, joints and coordinates (docs/calibration.md, "Angles for any
// template"): its side (r_thigh, LASI, R.ASIS, thigh_l, RightArm), which part
// of the body it is (thigh, shank, foot, ...) and the OpenSim coordinate names
// of the joint above it. Names only: no geometry here.
#pragma once

#include <string>
#include <vector>

namespace fabrik::calib {

enum class BodySide { none, right, left };

// One reading of a name as "a side token plus a stem": `key` names the
// pattern and the stem, so the mirror of a name is the other name with the
// same key and the opposite side. `explicit_token` is false for the bare
// Vicon prefix (RASI, LTHI), which is only a side when its mirror exists.
struct SideReading {
  std::string key;
  std::string stem;  // the name without the side token
  BodySide side = BodySide::none;
  bool explicit_token = false;
};
std::vector<SideReading> side_readings(const std::string& name);

// The side of each name in `names`: an explicit token (r_, _l, R., Right...)
// counts alone; a bare R/L prefix counts when its mirror is in `names` too.
std::vector<BodySide> sides_of(const std::vector<std::string>& names);

// Pairs (right index, left index) of mirrored names in `names`.
std::vector<std::pair<int, int>> mirrored_pairs(const std::vector<std::string>& names);

// The body part a segment name stands for, by its stem (the name without
// its side token, lower case, without '_', '.', '-' and spaces).
enum class BodyPart {
  unknown,
  pelvis,
  thigh,
  shank,
  foot,  // hindfoot, calcaneus, talus: the ankle's distal segment
  forefoot,
  toes,
  trunk,
  head,
  shoulder_girdle,  // clavicle, scapula
  upper_arm,
  forearm,
  hand,
};
BodyPart body_part(const std::string& segment_name);

// Limbs have proximal y axes (towards the trunk); the trunk and head have
// superior ones.
bool is_limb(BodyPart part);
// Segments ISB gives the frame of the segment above at the neutral posture
// (the calcaneus frame coincides with the tibia's): feet and toes.
bool takes_parent_frame(BodyPart part);

// OpenSim's names for the joint above a segment of this part, per Cardan
// angle (z, x, y); empty where OpenSim has none. Side suffixes are added by
// the caller.
struct JointCoordinateNames {
  std::string z, x, y;
};
JointCoordinateNames opensim_names(BodyPart part);

}  // namespace fabrik::calib
