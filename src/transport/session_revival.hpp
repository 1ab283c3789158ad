// A connecting socket's session that ZeroMQ gave up, connected again.
//
// libzmq 4.3.4 reconnects a connecting socket after a connection error, not
// after a protocol error: a peer of the wrong socket type (a PUB or a DEALER
// bound where the output connects, a SUB where the input does), a message
// over the socket's size limit (the input's), or any other break of the
// protocol ends the session, and the socket sends or receives nothing more
// until it is reopened.
// The socket monitor tells the two apart only by what follows: after a
// connection error ZeroMQ schedules a reconnection and reports it at once
// (ZMQ_EVENT_CONNECT_RETRIED); after a protocol error it reports nothing
// more. So a disconnection that no retry follows within `retry()` is taken
// as given up, and the daemon connects the socket again. `retry()` doubles,
// up to kMaxRetry, at each such connection, and starts afresh after a session
// that lasted kLastingSession: a peer that breaks the protocol right after each
// handshake (within milliseconds) is connected to ever less often, while a
// source that breaks it now and then waits the first second again, whatever
// came before. (A threshold that grew with the wait left a source that broke
// it every 20 s waiting 32 s each time, once a bad peer had grown the wait.)
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <zmq.hpp>

#include "socket_monitor.hpp"

namespace fabrik::wire {

// The rule alone, fed the monitor's event ids.
class RevivalRule {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr Clock::duration kFirstRetry = std::chrono::seconds(1);
  static constexpr Clock::duration kMaxRetry = std::chrono::seconds(32);
  // A session this long was no peer breaking each one at once (so at worst the
  // socket is up half the time); far above the loop's lag in reading events.
  static constexpr Clock::duration kLastingSession = std::chrono::seconds(1);
  // The monitor events the rule reads.
  static constexpr int kEvents =
      ZMQ_EVENT_DISCONNECTED | ZMQ_EVENT_CONNECT_RETRIED | ZMQ_EVENT_HANDSHAKE_SUCCEEDED;

  void on_event(std::uint16_t id, Clock::time_point now);
  bool due(Clock::time_point now) const { return down_since_ && now - *down_since_ >= retry_; }
  // The socket was connected again: the next give-up waits twice as long,
  // unless the session that follows lasts kLastingSession.
  void reconnected();
  // Connecting again failed: no event will come, so it is tried again after the (doubled) wait.
  void connect_failed(Clock::time_point now) { down_since_ = now; }
  Clock::duration retry() const { return retry_; }

 private:
  std::optional<Clock::time_point> down_since_;
  std::optional<Clock::time_point> up_since_;  // the handshake of the session now up
  Clock::duration retry_ = kFirstRetry;
};

// The rule over a monitor of its own, for the output socket (which must
// outlive it). The input's monitor, which also counts its disconnections,
// feeds a RevivalRule of its own.
class OutputRevival {
 public:
  OutputRevival() = default;
  OutputRevival(zmq::context_t& context, zmq::socket_t& output)
      : monitor_(context, output, RevivalRule::kEvents) {}
  explicit operator bool() const { return static_cast<bool>(monitor_); }
  zmq::socket_t& events() { return monitor_.events(); }
  // Reads the events waiting (a batch at most).
  void read(RevivalRule::Clock::time_point now);
  RevivalRule& rule() { return rule_; }

 private:
  SocketMonitor monitor_;
  RevivalRule rule_;
};

}  // namespace fabrik::wire
