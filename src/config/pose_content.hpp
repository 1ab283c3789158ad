// What a pose carries beyond the fields the wire contract requires
// (output.pose_content): a subscriber that needs joints and angles only need
// not pay for encoding, sending and parsing segments, gap ages and the rest.
// The required fields (frame, units, joints, markers, occluded, residual's
// rms/max/worst/count, solver's status/iterations/solve_us) and the header's
// echoes (time, stamp_us) are always written.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

#include "json_reader.hpp"

namespace fabrik {

// The pose's optional parts, named as the pose's fields (a dot for a member
// of residual or solver). `measured` has its own switch (output.measured_markers).
enum class PosePart : std::uint8_t {
  held,
  gap_s,
  outliers,
  relabelled,
  residual_quality,
  residual_beyond,
  angles,
  translations,
  segments,
  solver_stop,
};
inline constexpr std::array<std::string_view, 10> kPosePartNames = {
    "held",   "gap_s",        "outliers", "relabelled", "residual.quality", "residual.beyond",
    "angles", "translations", "segments", "solver.stop"};

class PoseContent {
 public:
  // Every part: the pose as it was before output.pose_content existed.
  static constexpr PoseContent all() { return PoseContent((1u << kPosePartNames.size()) - 1); }
  static constexpr PoseContent none() { return PoseContent(0); }
  constexpr bool has(PosePart p) const { return (bits_ >> static_cast<unsigned>(p)) & 1u; }
  constexpr PoseContent with(PosePart p) const {
    return PoseContent(bits_ | (1u << static_cast<unsigned>(p)));
  }
  constexpr bool operator==(const PoseContent&) const = default;

 private:
  constexpr explicit PoseContent(std::uint32_t bits) : bits_(bits) {}
  std::uint32_t bits_;
};

// An array of part names (each at most once); an unknown name fails with the list.
PoseContent read_pose_content(const JsonReader& value);

}  // namespace fabrik
