// The output's live subscriptions, as the loop sees them (XPUB_VERBOSER
// passes every subscription and every unsubscription, including those ZeroMQ
// makes for a subscriber that went away): who receives a topic, so that a
// pose (or a pose view, output.views) is encoded only while someone does.
// A subscription receives a topic when it is a prefix of it (ZeroMQ's rule);
// it selects a view's topic when it also is not a prefix of one of the
// daemon's own topics (so "" and "p" do not: they ask for every pose, not for
// a view). Changes only when a subscription arrives; the frame path reads
// counts the loop keeps.
//
// Per connection, as the XPUB holds them (one entry per connection and
// prefix): a connection's repeated subscription counts once, and it can only
// give up what it holds. A SUB socket subscribing twice sends both, but one
// unsubscription; a raw peer may send unsubscriptions of what others hold,
// which, counted, stopped their poses. A connection is its descriptor
// (ZMQ_SRCFD) and its socket's inode, so a new connection on a reused
// descriptor holds nothing of the last one's. ZeroMQ's own unsubscriptions,
// for a connection gone, name none: they end one count, and now and then the
// holders that are no longer alive are forgotten.
#pragma once

#include <algorithm>
#include <cstdint>
#include <iterator>
#include <map>
#include <set>
#include <string>
#include <string_view>

#include "config/topics.hpp"

namespace fabrik::wire {

// Who sent a subscription message: fd < 0 when ZeroMQ names no connection (its
// own unsubscriptions for a connection gone, an inproc peer's messages).
struct SubscriberConnection {
  int fd = -1;
  std::uint64_t inode = 0;
  auto operator<=>(const SubscriberConnection&) const = default;
};

class SubscriptionBook {
 public:
  void subscribed(std::string_view prefix, SubscriberConnection from = {}) {
    if (from.fd >= 0 && !holders_[std::string(prefix)].held.insert(from).second) return;  // a repeat
    ++count_[std::string(prefix)];
  }
  // An unsubscription of what was never counted (a refused subscription's, as
  // ZeroMQ reports it when that subscriber is dropped), or of what the sending
  // connection does not hold, changes nothing. `alive(connection)`: whether
  // that connection is still the one on its descriptor.
  template <class Alive>
  void unsubscribed(std::string_view prefix, SubscriberConnection from, Alive alive) {
    const auto holders = holders_.find(prefix);
    if (from.fd >= 0) {
      if (holders == holders_.end() || holders->second.held.erase(from) == 0) return;
    } else if (holders != holders_.end()) {
      // A connection gone stays among the holders (it can never match again: its inode
      // was its own) until they have doubled since the last sweep: a sweep on every such
      // unsubscription would ask the kernel about every holder each time one goes.
      Holders& h = holders->second;
      if (h.held.size() >= h.sweep_at) {
        std::erase_if(h.held, [&](const SubscriberConnection& c) { return !alive(c); });
        h.sweep_at = std::max<std::size_t>(kFirstSweep, 2 * h.held.size());
      }
    }
    if (holders != holders_.end() && holders->second.held.empty()) holders_.erase(holders);
    const auto it = count_.find(prefix);
    if (it == count_.end()) return;
    if (--it->second == 0) count_.erase(it);
  }
  void unsubscribed(std::string_view prefix) {
    unsubscribed(prefix, {}, [](const SubscriberConnection&) { return true; });
  }
  // The live subscriptions that select `topic`, each counted once per connection that
  // made it.
  int selecting(std::string_view topic) const {
    int n = 0;
    for (const auto& [prefix, count] : count_)
      if (!prefix.empty() && topic.starts_with(prefix) && !prefixes_own_topic(prefix)) n += count;
    return n;
  }
  // The live subscriptions that receive `topic` (as ZeroMQ matches them),
  // each counted once per connection that made it.
  int receiving(std::string_view topic) const {
    return count_if([&](std::string_view prefix) { return topic.starts_with(prefix); });
  }
  // The live subscriptions for which receives(prefix) holds, each counted once per
  // connection that made it.
  template <class Receives>
  int count_if(Receives receives) const {
    int n = 0;
    for (const auto& [prefix, count] : count_)
      if (receives(std::string_view(prefix))) n += count;
    return n;
  }
  // Connections held per prefix, summed (what the book keeps of them).
  std::size_t connections_held() const {
    std::size_t n = 0;
    for (const auto& [prefix, h] : holders_) n += h.held.size();
    return n;
  }
  void clear() {
    count_.clear();
    holders_.clear();
  }

 private:
  static bool prefixes_own_topic(std::string_view prefix) {
    return std::any_of(std::begin(kPublishedTopics), std::end(kPublishedTopics),
                       [&](std::string_view t) { return t.starts_with(prefix); });
  }
  std::map<std::string, int, std::less<>> count_;
  static constexpr std::size_t kFirstSweep = 16;
  struct Holders {
    std::set<SubscriberConnection> held;
    std::size_t sweep_at = kFirstSweep;
  };
  std::map<std::string, Holders, std::less<>> holders_;
};

}  // namespace fabrik::wire
