// The wire's topics (../shared/wire-contract.md, proto/README.md), named once:
// the daemon's subscription check, its pose views' selection and the rule for
// a view's topic all compare against these.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string_view>

namespace fabrik {

inline constexpr std::string_view kMarkersTopic = "markers";  // in
inline constexpr std::string_view kPublishedTopics[] = {"pose", "stats", "model"};  // out

// A pose view's topic (output.views) and a subject's name, which suffixes
// pose/, model/ and a view's topic in a multi-subject config.
inline constexpr std::size_t kMaxViewTopicBytes = 32;
inline constexpr std::size_t kMaxSubjectNameBytes = 32;
// No topic the daemon publishes is longer: TOPIC/NAME.
inline constexpr std::size_t kLongestTopicBytes =
    std::max({kMaxViewTopicBytes, kPublishedTopics[0].size(), kPublishedTopics[1].size(),
              kPublishedTopics[2].size()}) +
    1 + kMaxSubjectNameBytes;

}  // namespace fabrik
