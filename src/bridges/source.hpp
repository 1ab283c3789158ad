// What a vendor client (QTM, NatNet) hands to fabrikd, and how it reports its
// connection. A client runs on a thread of its own: it connects, streams,
// and on any failure (refused, wrong version, stalled, malformed, truncated
// or oversized packet, server gone) records the error, waits with backoff
// and connects again, until it is asked to stop. It never throws and never
// logs: fabrikd's transport reads SourceStatus and logs what changed.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <mutex>
#include <span>
#include <string>
#include <string_view>

namespace fabrik::bridges {

// "host:port" for messages, an IPv6 address in brackets ("[::1]:22223", not "::1:22223").
inline std::string host_port(const std::string& host, std::uint16_t port) {
  const bool ipv6 = host.find(':') != std::string::npos;
  return (ipv6 ? "[" + host + "]" : host) + ":" + std::to_string(port);
}

// Where the frames go, called on the client's thread only.
class FrameSink {
 public:
  virtual ~FrameSink() = default;
  // The names of the positions in the frames that follow, as the server
  // names them (a subject prefix such as "Subject:" is kept). Called after
  // every (re)connection and whenever the server's labels change.
  virtual void labels(std::span<const std::string> names) = 0;
  // The up axis the server states for its positions, as it spells it (QTM's AxisUpwards,
  // "+Z"), just before labels(); never called by a server that states none (Motive).
  virtual void up_axis(std::string_view /*axis*/) {}
  // One frame: p_server_mm[i] belongs to labels()[i], in the server's own
  // axes, millimetres; NaN where the server does not see the marker.
  // `time_s` is the server's timestamp (NaN when it sends none).
  virtual void frame(std::uint64_t frame_number, double time_s,
                     std::span<const Eigen::Vector3d> p_server_mm) = 0;
};

// Timeouts and backoff shared by the clients.
struct ConnectionPolicy {
  double connect_timeout_s = 2.0;  // TCP connect, or the first reply of a handshake
  double reply_timeout_s = 2.0;    // any command's reply; the rest of a started packet
  double stall_timeout_s = 3.0;    // streaming and no frame for this long: reconnect
  double reconnect_min_s = 0.1;    // first wait after a failure, doubled each failure
  double reconnect_max_s = 5.0;    // the longest wait
  std::size_t max_packet_bytes = std::size_t{16} << 20;  // larger is an error, not a buffer

  bool operator==(const ConnectionPolicy&) const = default;
};

// Waits between attempts: min, 2 min, 4 min ... max; reset once connected.
class Backoff {
 public:
  explicit Backoff(const ConnectionPolicy& p) : min_s_(p.reconnect_min_s), max_s_(p.reconnect_max_s) {}
  double next_wait_s() {
    const double wait = std::min(max_s_, next_s_ > 0 ? next_s_ : min_s_);
    next_s_ = std::min(max_s_, wait * 2.0);
    return wait;
  }
  void reset() { next_s_ = 0.0; }

 private:
  double min_s_, max_s_, next_s_ = 0.0;
};

// The connection as stats show it; written by the client's thread, read by
// the daemon's (a mutex: a few updates per connection, one read a second).
class SourceStatus {
 public:
  struct Snapshot {
    bool connected = false;
    std::uint64_t connections = 0;  // successful handshakes
    std::uint64_t reconnects = 0;   // connections after the first
    std::uint64_t errors = 0;       // failures of any kind (each also sets last_error)
    std::uint64_t frames = 0;       // frames handed to the sink
    std::uint64_t bad_packets = 0;  // packets refused (malformed, truncated, oversized)
    std::string server;             // e.g. "QTM RT protocol 1.23" or "Motive 3.1.0, NatNet 4.1"
    std::string last_error;         // empty until the first failure
    std::uint64_t notices = 0;      // notice() calls
    std::string last_notice;
  };

  // After a successful handshake.
  void connected(std::string_view server) {
    std::lock_guard lock(mutex_);
    s_.connected = true;
    if (++s_.connections > 1) ++s_.reconnects;
    s_.server.assign(server.substr(0, 200));
  }
  void disconnected() {
    std::lock_guard lock(mutex_);
    s_.connected = false;
  }
  // Any failure: the text says what and, where it helps, the fix.
  void error(std::string_view what) {
    std::lock_guard lock(mutex_);
    ++s_.errors;
    s_.last_error.assign(what.substr(0, 240));
  }
  // Something the user should read that is not a failure (e.g. how the server's axes
  // are taken): logged once each time it changes.
  void notice(std::string_view what) {
    std::lock_guard lock(mutex_);
    ++s_.notices;
    s_.last_notice.assign(what.substr(0, 400));
  }
  // A packet refused; also an error.
  void bad_packet(std::string_view what) {
    std::lock_guard lock(mutex_);
    ++s_.bad_packets;
    ++s_.errors;
    s_.last_error.assign(what.substr(0, 240));
  }
  // Called just before the frame is handed to the sink, so that a stats message read
  // between the two never shows fewer frames than the poses they have caused.
  void frame_delivered() {
    std::lock_guard lock(mutex_);
    ++s_.frames;
  }
  Snapshot snapshot() const {
    std::lock_guard lock(mutex_);
    return s_;
  }

 private:
  mutable std::mutex mutex_;
  Snapshot s_;
};

}  // namespace fabrik::bridges
