#include "socket_monitor.hpp"

#include <atomic>
#include <cstring>
#include <string>
#include <utility>

namespace fabrik::wire {

SocketMonitor::SocketMonitor(zmq::context_t& context, zmq::socket_t& watched, int events) {
  static std::atomic<int> monitors{0};
  const std::string address = "inproc://fabrik-socket-monitor-" + std::to_string(++monitors);
  if (zmq_socket_monitor(watched.handle(), address.c_str(), events) != 0) return;
  watched_ = watched.handle();
  events_ = zmq::socket_t(context, zmq::socket_type::pair);
  events_.set(zmq::sockopt::linger, 0);
  events_.connect(address);
}

SocketMonitor::SocketMonitor(SocketMonitor&& other) noexcept
    : watched_(std::exchange(other.watched_, nullptr)), events_(std::move(other.events_)) {}

SocketMonitor& SocketMonitor::operator=(SocketMonitor&& other) noexcept {
  if (this != &other) {
    stop();
    watched_ = std::exchange(other.watched_, nullptr);
    events_ = std::move(other.events_);
  }
  return *this;
}

std::optional<SocketMonitor::Event> SocketMonitor::next() {
  zmq::message_t event, address;
  while (events_.recv(event, zmq::recv_flags::dontwait)) {
    if (event.more()) (void)events_.recv(address, zmq::recv_flags::dontwait);
    if (event.size() < 6) continue;
    Event e;
    std::memcpy(&e.id, event.data(), 2);
    std::memcpy(&e.value, static_cast<const char*>(event.data()) + 2, 4);
    return e;
  }
  return std::nullopt;
}

SocketMonitor::~SocketMonitor() {
  stop();
}

void SocketMonitor::stop() noexcept {
  if (watched_) (void)zmq_socket_monitor(watched_, nullptr, 0);
  watched_ = nullptr;
  events_.close();
}

}  // namespace fabrik::wire
