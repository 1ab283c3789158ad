// A socket's connection events (ZeroMQ's socket monitor), read from a PAIR.
// ZeroMQ's I/O thread sends each event with a blocking send: once the
// reading end is closed, the next event (a peer that disconnects) blocks
// that thread for good and every socket of the context stops connecting
// (libzmq issue 3575). So monitoring stops before the reading end closes,
// and the watched socket must outlive this object.
#pragma once

#include <cstdint>
#include <optional>
#include <zmq.hpp>

namespace fabrik::wire {

class SocketMonitor {
 public:
  SocketMonitor() = default;
  // Watches `events` (ZMQ_EVENT_*) of `watched`; empty if ZeroMQ refuses.
  SocketMonitor(zmq::context_t& context, zmq::socket_t& watched, int events);
  SocketMonitor(SocketMonitor&& other) noexcept;
  SocketMonitor& operator=(SocketMonitor&& other) noexcept;
  SocketMonitor(const SocketMonitor&) = delete;
  SocketMonitor& operator=(const SocketMonitor&) = delete;
  ~SocketMonitor();

  explicit operator bool() const { return static_cast<bool>(events_); }
  zmq::socket_t& events() { return events_; }
  struct Event {
    std::uint16_t id = 0;     // ZMQ_EVENT_*
    std::uint32_t value = 0;  // its value (an errno, a descriptor, ...)
  };
  // The next event waiting, without blocking; nothing when none is.
  std::optional<Event> next();

 private:
  void stop() noexcept;
  void* watched_ = nullptr;  // the monitored socket's handle
  zmq::socket_t events_;     // the reading end
};

}  // namespace fabrik::wire
