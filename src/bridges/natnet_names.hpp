// Marker names of a NatNet stream and their match to a model's marker names.
// Motive names an asset's markers `Subject:Marker` (marker set or skeleton
// asset name, a colon, the marker's label); a model names them `Marker`.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "bridges/natnet_protocol.hpp"

namespace fabrik::natnet {

// `Set:Marker` for each marker of the set, in its order; a name that already
// has a `Subject:` part is kept as it is.
std::vector<std::string> qualified_marker_names(const MarkerSetDescription& set);

// The marker name with its subject part removed. An empty prefix removes any
// `Subject:` (up to the first colon); a prefix removes only itself, with or
// without its colon ("subject01" and "subject01:" both strip "subject01:"; a
// prefix ending in a separator such as "s1_" strips just itself).
// A name that does not start with the prefix is returned unchanged.
std::string_view strip_subject_prefix(std::string_view name, std::string_view prefix);

// For each model marker name, the index in `stream_names` of the first name
// that equals it after strip_subject_prefix, or -1 if none does.
std::vector<int> match_model_markers(const std::vector<std::string>& model_names,
                                     const std::vector<std::string>& stream_names,
                                     std::string_view prefix);

}  // namespace fabrik::natnet
