// The wire's topics (../shared/wire-contract.md, proto/README.md), named once:
// the daemon's subscription check, its pose views' selection and the rule for
// a view's topic all compare against these.
#pragma once

#include <string_view>

namespace fabrik {

inline constexpr std::string_view kMarkersTopic = "markers";  // in
inline constexpr std::string_view kPublishedTopics[] = {"pose", "stats", "model"};  // out

}  // namespace fabrik
