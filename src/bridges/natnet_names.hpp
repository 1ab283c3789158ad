// Marker names of a NatNet stream. Motive names an asset's markers `Subject:Marker` (marker set
// or skeleton asset name, a colon, the marker's label); the source takes the subject off
// (wire::strip_subject_prefix, source_frames.hpp).
#pragma once

#include <string>
#include <vector>

#include "bridges/natnet_protocol.hpp"

namespace fabrik::natnet {

// `Set:Marker` for each marker of the set, in its order; a name that already
// has a `Subject:` part is kept as it is.
std::vector<std::string> qualified_marker_names(const MarkerSetDescription& set);

}  // namespace fabrik::natnet
