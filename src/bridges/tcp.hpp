// TCP for the vendor clients and simulators with every wait bounded: sockets
// are non-blocking and each wait is cut into slices of at most 100 ms, so a
// stop request is seen within a slice. Errors are values (text), not
// exceptions, except when a listener cannot be set up.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <span>
#include <stop_token>
#include <string>

namespace fabrik::bridges {

using Clock = std::chrono::steady_clock;
inline constexpr std::chrono::milliseconds kPollSlice{100};

inline Clock::time_point deadline_after(double seconds) {
  return Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

// An owned file descriptor.
class Fd {
 public:
  Fd() = default;
  explicit Fd(int fd) : fd_(fd) {}
  Fd(Fd&& o) noexcept : fd_(o.release()) {}
  Fd& operator=(Fd&& o) noexcept;
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() { reset(); }
  int get() const { return fd_; }
  bool valid() const { return fd_ >= 0; }
  int release();
  void reset();

 private:
  int fd_ = -1;
};

// Connects to host:port before `timeout_s` (TCP_NODELAY set, non-blocking).
// An invalid Fd and a reason in `error` on failure or stop. Name lookup uses
// getaddrinfo, bounded by the resolver's own timeouts; numeric hosts do not wait.
Fd connect_tcp(const std::string& host, std::uint16_t port, double timeout_s, const std::stop_token& stop,
               std::string& error);

enum class WaitResult { ready, timeout, stopped, failed };
// Waits for `events` (POLLIN/POLLOUT) on fd until the deadline, in slices.
WaitResult wait_fd(int fd, short events, Clock::time_point deadline, const std::stop_token& stop);

// Sends every byte before the deadline; false with a reason otherwise.
bool send_all(int fd, std::span<const std::uint8_t> bytes, Clock::time_point deadline,
              const std::stop_token& stop, std::string& error);

// Sends what the socket takes now: bytes sent, or -1 on a broken connection.
long send_some(int fd, std::span<const std::uint8_t> bytes);

// Reads what is there now: >0 bytes read, 0 the peer closed, -1 nothing yet, -2 error.
long read_some(int fd, std::span<std::uint8_t> buffer);

// A non-blocking listener on address:port (0: any free port), SO_REUSEADDR so a
// restarted simulator gets its port back. Invalid Fd and a reason on failure;
// `bound_port` receives the port.
Fd listen_tcp(const std::string& address, std::uint16_t port, std::uint16_t& bound_port, std::string& error);

// A non-blocking accepted connection with TCP_NODELAY, or an invalid Fd.
Fd accept_tcp(int listener);

}  // namespace fabrik::bridges
