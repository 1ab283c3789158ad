#include "bridges/natnet_names.hpp"

#include <cctype>
#include <unordered_map>

namespace fabrik::natnet {

std::vector<std::string> qualified_marker_names(const MarkerSetDescription& set) {
  std::vector<std::string> names;
  names.reserve(set.marker_names.size());
  for (const auto& marker : set.marker_names)
    names.push_back(marker.find(':') != std::string::npos ? marker : set.name + ":" + marker);
  return names;
}

std::string_view strip_subject_prefix(std::string_view name, std::string_view prefix) {
  if (prefix.empty()) {
    const auto colon = name.find(':');
    return colon == std::string_view::npos ? name : name.substr(colon + 1);
  }
  if (!name.starts_with(prefix)) return name;
  std::string_view rest = name.substr(prefix.size());
  // A prefix ending in a letter or digit ends only at a colon: "subject" must
  // not strip "subject01:"; one ending in a separator ("s1_", "s1:") is whole.
  if (std::isalnum(static_cast<unsigned char>(prefix.back())) != 0) {
    if (!rest.starts_with(':')) return name;
    rest.remove_prefix(1);
  }
  return rest;
}

std::vector<int> match_model_markers(const std::vector<std::string>& model_names,
                                     const std::vector<std::string>& stream_names,
                                     std::string_view prefix) {
  std::unordered_map<std::string_view, int> index;
  for (std::size_t i = 0; i < stream_names.size(); ++i)
    index.try_emplace(strip_subject_prefix(stream_names[i], prefix), static_cast<int>(i));
  std::vector<int> match;
  match.reserve(model_names.size());
  for (const auto& name : model_names) {
    const auto it = index.find(name);
    match.push_back(it == index.end() ? -1 : it->second);
  }
  return match;
}

}  // namespace fabrik::natnet
