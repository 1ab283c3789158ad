#include "session_revival.hpp"

#include <algorithm>

namespace fabrik::wire {

void RevivalRule::on_event(std::uint16_t id, Clock::time_point now) {
  if (id == ZMQ_EVENT_DISCONNECTED) {
    if (up_since_ && now - *up_since_ >= kLastingSession) retry_ = kFirstRetry;
    up_since_.reset();
    if (!down_since_) down_since_ = now;
  } else if (id == ZMQ_EVENT_CONNECT_RETRIED) {
    down_since_.reset();  // ZeroMQ reconnects by itself
  } else if (id == ZMQ_EVENT_HANDSHAKE_SUCCEEDED) {
    // The peer answered as the socket's kind of peer: the session is up (a disconnection
    // read before it was the last one's).
    down_since_.reset();
    up_since_ = now;
  }
}

void RevivalRule::reconnected() {
  down_since_.reset();
  retry_ = std::min(2 * retry_, kMaxRetry);
}

void OutputRevival::read(RevivalRule::Clock::time_point now) {
  constexpr int kMaxBatch = 64;
  for (int n = 0; n < kMaxBatch; ++n) {
    const std::optional<SocketMonitor::Event> event = monitor_.next();
    if (!event) break;
    rule_.on_event(event->id, now);
  }
}

}  // namespace fabrik::wire
