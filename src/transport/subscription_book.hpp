// The output's live subscriptions, as the loop sees them (XPUB_VERBOSER
// passes every subscription and every unsubscription, including those ZeroMQ
// makes for a subscriber that went away): who receives a topic, so that a
// pose (or a pose view, output.views) is encoded only while someone does.
// A subscription receives a topic when it is a prefix of it (ZeroMQ's rule);
// it selects a view's topic when it also is not a prefix of one of the
// daemon's own topics (so "" and "p" do not: they ask for every pose, not for
// a view). Changes only when a subscription arrives; the frame path reads
// counts the loop keeps.
#pragma once

#include <algorithm>
#include <iterator>
#include <map>
#include <string>
#include <string_view>

#include "config/topics.hpp"

namespace fabrik::wire {

class SubscriptionBook {
 public:
  void subscribed(std::string_view prefix) { ++count_[std::string(prefix)]; }
  // An unsubscription of what was never counted (a refused subscription's, as
  // ZeroMQ reports it when that subscriber is dropped) changes nothing.
  void unsubscribed(std::string_view prefix) {
    const auto it = count_.find(prefix);
    if (it == count_.end()) return;
    if (--it->second == 0) count_.erase(it);
  }
  // The live subscriptions that select `topic`, each counted as often as it was made.
  int selecting(std::string_view topic) const {
    int n = 0;
    for (const auto& [prefix, count] : count_)
      if (!prefix.empty() && topic.starts_with(prefix) && !prefixes_own_topic(prefix)) n += count;
    return n;
  }
  // The live subscriptions that receive `topic` (as ZeroMQ matches them),
  // each counted as often as it was made.
  int receiving(std::string_view topic) const {
    return count_if([&](std::string_view prefix) { return topic.starts_with(prefix); });
  }
  // The live subscriptions for which receives(prefix) holds, each counted as often as it was made.
  template <class Receives>
  int count_if(Receives receives) const {
    int n = 0;
    for (const auto& [prefix, count] : count_)
      if (receives(std::string_view(prefix))) n += count;
    return n;
  }
  void clear() { count_.clear(); }

 private:
  static bool prefixes_own_topic(std::string_view prefix) {
    return std::any_of(std::begin(kPublishedTopics), std::end(kPublishedTopics),
                       [&](std::string_view t) { return t.starts_with(prefix); });
  }
  std::map<std::string, int, std::less<>> count_;
};

}  // namespace fabrik::wire
