#include "bridges/natnet_names.hpp"

namespace fabrik::natnet {

std::vector<std::string> qualified_marker_names(const MarkerSetDescription& set) {
  std::vector<std::string> names;
  names.reserve(set.marker_names.size());
  for (const auto& marker : set.marker_names)
    names.push_back(marker.find(':') != std::string::npos ? marker : set.name + ":" + marker);
  return names;
}

}  // namespace fabrik::natnet
