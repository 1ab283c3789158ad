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
// Unsubscriptions count only when they can be told to give up something
// held: XPUB_VERBOSER passes every unsubscription a peer sends, held or not,
// and a raw peer's unsubscriptions of what others held, counted, brought the
// count to 0 and stopped their poses. A peer's subscription is kept against
// its connection (the descriptor ZeroMQ names, ZMQ_SRCFD, and that socket's
// inode, as the loop finds them when it reads the message), and its
// unsubscription counts only against such a record; one from a connection
// already closed when the loop reads it does not count. ZeroMQ's own
// unsubscriptions, for a connection gone (and an inproc peer's messages),
// name no descriptor and count as they come (so a refused subscription to a
// prefix still counted, a topic a reload dropped, is counted: refused()).
// Where the loop cannot tell, it errs on the side of a count too high (a pose
// made for no one), never too low (a subscriber's poses not made): a
// connection that subscribes twice counts twice, and ZeroMQ sends one
// unsubscription for both.
//
// A connected output has one peer (the operator's proxy) on one ZeroMQ pipe,
// which its socket keeps across reconnections (ZMQ_IMMEDIATE 0): every
// message is that peer's, and ZeroMQ holds a prefix for a pipe or not. The
// peer's prefixes are kept as a set, so a subscription sent again (at each
// reconnection, or twice) counts once and its unsubscription ends it
// (docs/hardening.md: the cases where it is still not exact). What the
// daemon refused from that peer ZeroMQ keeps too (the proxy is not dropped):
// it is kept here, short ones only, should a reload make it select a topic.
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

// Who sent a subscription message, as far as the loop can tell when it reads it.
struct SubscriptionSender {
  enum class Kind : std::uint8_t {
    zeromq,      // no descriptor: ZeroMQ's own unsubscription for a connection gone, or inproc
    connection,  // a descriptor still open: fd and its socket's inode
    gone,        // a descriptor already closed
    peer,        // a connected output's one peer (its pipe holds a prefix or not)
  };
  Kind kind = Kind::zeromq;
  int fd = -1;
  std::uint64_t inode = 0;
  auto operator<=>(const SubscriptionSender&) const = default;
};

class SubscriptionBook {
 public:
  void subscribed(std::string_view prefix, SubscriptionSender from = {}) {
    if (from.kind == SubscriptionSender::Kind::peer && !peer_holds_.emplace(prefix).second) return;
    ++count_[std::string(prefix)];
    if (from.kind == SubscriptionSender::Kind::connection) ++held_[std::string(prefix)].by[from];
  }
  // A subscription the daemon refused (a prefix of none of its topics). ZeroMQ
  // holds it all the same. A connected output's peer keeps it (the proxy is not
  // dropped), so it is kept here too, if no longer than any topic can be. On a
  // bound output the subscriber is dropped and ZeroMQ then unsubscribes it as
  // its own, which counts: where the prefix is counted (a topic a reload
  // dropped, its earlier subscribers still counted) it is counted too, or that
  // unsubscription would take an earlier subscriber's count. Other refused
  // prefixes are not counted: they are the sender's to choose, and would make
  // the book grow. A connection's pipe holds a prefix once, and ZeroMQ
  // unsubscribes it once: a connection's second subscription to it (a SUB
  // subscribing twice) is not counted again.
  void refused(std::string_view prefix, SubscriptionSender from) {
    if (from.kind == SubscriptionSender::Kind::peer) {
      if (prefix.size() <= kLongestTopicBytes) peer_refused_.emplace(prefix);
      return;
    }
    if (!count_.contains(prefix)) return;
    if (from.kind == SubscriptionSender::Kind::connection) {
      const auto held = held_.find(prefix);
      if (held != held_.end() && held->second.by.contains(from)) return;
    }
    subscribed(prefix, from);
  }
  // After a reload that kept the output: the peer's refused subscriptions that
  // now select a topic (`valid`) count.
  template <class Valid>
  void revalidate(Valid valid) {
    std::erase_if(peer_refused_, [&](const std::string& prefix) {
      if (!valid(std::string_view(prefix))) return false;
      subscribed(prefix, SubscriptionSender{SubscriptionSender::Kind::peer});
      return true;
    });
  }
  // Counts only what can be told to be held (above); an unsubscription of what
  // was never counted (a refused subscription's, as ZeroMQ reports it when that
  // subscriber is dropped) changes nothing. `still_open(sender)`: whether that
  // descriptor is still that socket (records of those that are not are dropped).
  template <class StillOpen>
  bool unsubscribed(std::string_view prefix, SubscriptionSender from, StillOpen still_open) {
    const auto held = held_.find(prefix);
    if (from.kind == SubscriptionSender::Kind::gone) return false;
    if (from.kind == SubscriptionSender::Kind::peer) {
      if (const auto refused = peer_refused_.find(prefix); refused != peer_refused_.end())
        peer_refused_.erase(refused);
      const auto it = peer_holds_.find(prefix);
      if (it == peer_holds_.end()) return false;
      peer_holds_.erase(it);
    } else if (from.kind == SubscriptionSender::Kind::connection) {
      if (held == held_.end()) return false;
      const auto it = held->second.by.find(from);
      if (it == held->second.by.end()) return false;
      if (--it->second == 0) held->second.by.erase(it);
    } else if (held != held_.end()) {
      // Records of connections gone can never match again (a later socket has another
      // inode); they go when a prefix's records have doubled since the last look, so
      // the kernel is asked about each at most as often as records come.
      Held& h = held->second;
      if (h.by.size() >= h.look_at) {
        std::erase_if(h.by, [&](const auto& record) { return !still_open(record.first); });
        h.look_at = std::max<std::size_t>(kFirstLook, 2 * h.by.size());
      }
    }
    if (held != held_.end() && held->second.by.empty()) held_.erase(held);
    const auto it = count_.find(prefix);
    if (it == count_.end()) return false;
    if (--it->second == 0) count_.erase(it);
    return true;
  }
  // The live subscriptions that select `topic`, each counted as often as it was
  // made.
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
  // The live subscriptions for which receives(prefix) holds, each counted as often as
  // it was made.
  template <class Receives>
  int count_if(Receives receives) const {
    int n = 0;
    for (const auto& [prefix, count] : count_)
      if (receives(std::string_view(prefix))) n += count;
    return n;
  }
  // The records of connections kept, over every prefix.
  std::size_t connection_records() const {
    std::size_t n = 0;
    for (const auto& [prefix, h] : held_) n += h.by.size();
    return n;
  }
  void clear() {
    count_.clear();
    held_.clear();
    peer_holds_.clear();
    peer_refused_.clear();
  }

 private:
  static bool prefixes_own_topic(std::string_view prefix) {
    return std::any_of(std::begin(kPublishedTopics), std::end(kPublishedTopics),
                       [&](std::string_view t) { return t.starts_with(prefix); });
  }
  std::map<std::string, int, std::less<>> count_;
  static constexpr std::size_t kFirstLook = 16;
  struct Held {
    std::map<SubscriptionSender, int> by;  // subscriptions per connection
    std::size_t look_at = kFirstLook;
  };
  std::map<std::string, Held, std::less<>> held_;
  std::set<std::string, std::less<>> peer_holds_;  // a connected output's peer's prefixes
  std::set<std::string, std::less<>> peer_refused_;  // and those the daemon refused
};

}  // namespace fabrik::wire
