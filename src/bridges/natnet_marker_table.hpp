// Which NatNet positions fabrikd receives and under which names: the markers
// of the described marker sets, named `Set:Marker`, in description order.
//
// How marker sets and labelled markers combine: the marker sets give the
// names, the order and the positions (Motive writes each asset's markers as
// one marker set: a marker-set asset, or a skeleton's or rigid body's markers
// under its name). The labelled markers only say what Motive did not see: a
// marker is NaN when
//   - its marker-set position is (0,0,0) or not finite (Motive's "no data"), or
//   - a labelled marker at bit-for-bit the same position carries the occluded
//     flag (the position is Motive's model-solved guess, not a measurement).
// Matching by position, not id, because a marker set's description carries no
// asset id to join labelled-marker ids (asset << 16 | member) to; Motive
// writes the same float for both, and two markers never share a position.
// The set named "all" (older Motive: every labelled marker again) is skipped.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "bridges/natnet_protocol.hpp"

namespace fabrik::natnet {

class MarkerTable {
 public:
  void reset(const ModelDefinitions& defs);
  const std::vector<std::string>& names() const { return names_; }
  // p_mm (resized to names().size()) in the server's axes, millimetres.
  // False, with the reason, when the frame does not fit the definitions (a
  // marker set not described or with another marker count, a rigid body or
  // skeleton id not described): the definitions are out of date.
  bool fill(const FrameOfData& frame, std::vector<Eigen::Vector3d>& p_mm, std::string& why);

 private:
  struct Set {
    std::string name;
    std::size_t first = 0, count = 0;
  };
  std::vector<Set> sets_;
  std::vector<std::int32_t> rigid_body_ids_, skeleton_ids_;
  std::vector<std::string> names_;
  std::vector<Point3f> occluded_;  // scratch, reused across frames
};

}  // namespace fabrik::natnet
