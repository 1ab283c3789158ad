#include "socket_options.hpp"

#include <algorithm>
#include <cstdint>

#include "daemon.hpp"

namespace fabrik::wire {

namespace {

// ZeroMQ refuses a message this large before buffering it, and drops the
// peer that sent it (a connecting source reconnects by itself). Up to it,
// an oversized payload reaches the decoder, which counts it in decode_errors.
std::int64_t zmq_max_message_bytes(const DaemonConfig& c) {
  return static_cast<std::int64_t>(2 * c.max_payload_bytes + 4096);
}

int input_queue_messages(const DaemonConfig& c) {
  return static_cast<int>(std::clamp<std::int64_t>(
      static_cast<std::int64_t>(kInputQueueBytes) / zmq_max_message_bytes(c), 16, 1000));
}

}  // namespace

void set_input_limits(zmq::socket_t& s, const DaemonConfig& c) {
  s.set(zmq::sockopt::maxmsgsize, zmq_max_message_bytes(c));
  s.set(zmq::sockopt::rcvhwm, input_queue_messages(c));
}

void set_input_options(zmq::socket_t& s, const DaemonConfig& c) {
  s.set(zmq::sockopt::linger, 0);
  s.set(zmq::sockopt::subscribe, "markers");
  set_input_limits(s, c);
  s.set(zmq::sockopt::handshake_ivl, kHandshakeTimeoutMs);
  s.set(zmq::sockopt::rcvbuf, kInputReceiveBufferBytes);
}

void set_output_limits(zmq::socket_t& s, const DaemonConfig& c) {
  s.set(zmq::sockopt::sndhwm, pose_queue_messages(c.max_backlog_frames));
}

void set_output_options(zmq::socket_t& s, const DaemonConfig& c) {
  s.set(zmq::sockopt::linger, 0);
  set_output_limits(s, c);
  s.set(zmq::sockopt::sndbuf, kPoseSendBufferBytes);
  // Every subscription also comes to the loop (Daemon::read_subscriptions),
  // with the connection it came from. (ZMQ_XPUB_MANUAL would let the loop
  // apply them itself, but libzmq 4.3 then pairs a message that is not a
  // subscription with the next subscription's connection.)
  s.set(zmq::sockopt::xpub_verboser, true);
  // On a bound output, a subscriber's long message drops only that subscriber.
  // A connected output's one peer is the operator's proxy, which forwards its own
  // clients' subscriptions: there a message too long is a protocol error that ends
  // the session for good (libzmq 4.3.4 does not reconnect after one), so one
  // client's long subscription would silence the output. Its size is left to the
  // proxy (its own ZMQ_MAXMSGSIZE). (ZMQ_IMMEDIATE stays 0: the connecting pipe
  // outlives each connection, which the subscription book relies on.)
  if (c.output.mode == SocketMode::bind) s.set(zmq::sockopt::maxmsgsize, kMaxSubscriptionBytes);
  s.set(zmq::sockopt::rcvhwm, kSubscriptionQueueMessages);
  s.set(zmq::sockopt::rcvbuf, kSubscriberReceiveBufferBytes);
}

}  // namespace fabrik::wire
