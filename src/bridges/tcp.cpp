#include "bridges/tcp.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace fabrik::bridges {

Fd& Fd::operator=(Fd&& o) noexcept {
  if (this != &o) {
    reset();
    fd_ = o.release();
  }
  return *this;
}

int Fd::release() {
  const int fd = fd_;
  fd_ = -1;
  return fd;
}

void Fd::reset() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

namespace {

bool set_nonblocking(int fd) {
  const int flags = ::fcntl(fd, F_GETFL, 0);
  return flags >= 0 && ::fcntl(fd, F_SETFL, flags | O_NONBLOCK) == 0;
}

void set_nodelay(int fd) {
  const int one = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
}

std::string errno_text(int e) { return std::strerror(e); }

}  // namespace

WaitResult wait_fd(int fd, short events, Clock::time_point deadline, const std::stop_token& stop) {
  for (;;) {
    if (stop.stop_requested()) return WaitResult::stopped;
    const auto now = Clock::now();
    if (now >= deadline) return WaitResult::timeout;
    const auto slice = std::min<Clock::duration>(deadline - now, kPollSlice);
    const int ms = static_cast<int>(std::chrono::ceil<std::chrono::milliseconds>(slice).count());
    pollfd p{fd, events, 0};
    const int n = ::poll(&p, 1, ms);
    if (n < 0) {
      if (errno == EINTR) continue;
      return WaitResult::failed;
    }
    if (n > 0) return WaitResult::ready;  // includes POLLERR/POLLHUP: the read or send says which
  }
}

Fd connect_tcp(const std::string& host, std::uint16_t port, double timeout_s, const std::stop_token& stop,
               std::string& error) {
  const auto deadline = deadline_after(timeout_s);
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_NUMERICSERV;
  addrinfo* found = nullptr;
  const std::string service = std::to_string(port);
  if (const int rc = ::getaddrinfo(host.c_str(), service.c_str(), &hints, &found); rc != 0) {
    // A name the resolver says does not exist is the user's to fix; another failure (no
    // answer now, EAI_AGAIN) the network's.
    error = (rc == EAI_NONAME ? "no host is named '" + host + "' (" + ::gai_strerror(rc) + ")"
                              : "cannot resolve host '" + host + "' now: " + ::gai_strerror(rc));
    return Fd();
  }
  error = "no address for host '" + host + "'";
  for (addrinfo* a = found; a != nullptr; a = a->ai_next) {
    Fd fd(::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol));
    if (!fd.valid() || !set_nonblocking(fd.get())) {
      error = "socket: " + errno_text(errno);
      continue;
    }
    set_nodelay(fd.get());
    if (::connect(fd.get(), a->ai_addr, a->ai_addrlen) != 0 && errno != EINPROGRESS) {
      error = errno_text(errno);
      continue;
    }
    const WaitResult w = wait_fd(fd.get(), POLLOUT, deadline, stop);
    if (w == WaitResult::stopped) {
      error = "stopped";
      break;
    }
    if (w == WaitResult::timeout) {
      error = "no answer within " + std::to_string(timeout_s).substr(0, 4) + " s";
      continue;
    }
    int so_error = 0;
    socklen_t len = sizeof so_error;
    if (::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &so_error, &len) != 0) so_error = errno;
    if (so_error != 0) {
      error = errno_text(so_error);
      continue;
    }
    ::freeaddrinfo(found);
    error.clear();
    return fd;
  }
  ::freeaddrinfo(found);
  return Fd();
}

long send_some(int fd, std::span<const std::uint8_t> bytes) {
  for (;;) {
    const ssize_t n = ::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL);
    if (n >= 0) return static_cast<long>(n);
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) return 0;
    return -1;
  }
}

bool send_all(int fd, std::span<const std::uint8_t> bytes, Clock::time_point deadline,
              const std::stop_token& stop, std::string& error) {
  std::size_t sent = 0;
  while (sent < bytes.size()) {
    const long n = send_some(fd, bytes.subspan(sent));
    if (n < 0) {
      error = "send failed: " + errno_text(errno);
      return false;
    }
    sent += static_cast<std::size_t>(n);
    if (sent == bytes.size()) break;
    const WaitResult w = wait_fd(fd, POLLOUT, deadline, stop);
    if (w == WaitResult::stopped) {
      error = "stopped";
      return false;
    }
    if (w != WaitResult::ready) {
      error = "the peer does not take our bytes (send stalled)";
      return false;
    }
  }
  return true;
}

long read_some(int fd, std::span<std::uint8_t> buffer) {
  for (;;) {
    const ssize_t n = ::recv(fd, buffer.data(), buffer.size(), 0);
    if (n >= 0) return static_cast<long>(n);
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) return -1;
    return -2;
  }
}

Fd listen_tcp(const std::string& address, std::uint16_t port, std::uint16_t& bound_port, std::string& error) {
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  if (::inet_pton(AF_INET, address.c_str(), &addr.sin_addr) != 1) {
    error = "'" + address + "' is not an IPv4 address";
    return Fd();
  }
  Fd fd(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
  if (!fd.valid()) {
    error = "socket: " + errno_text(errno);
    return Fd();
  }
  const int one = 1;
  ::setsockopt(fd.get(), SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  if (::bind(fd.get(), reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    error = "cannot bind " + address + ":" + std::to_string(port) + ": " + errno_text(errno);
    return Fd();
  }
  if (::listen(fd.get(), 16) != 0 || !set_nonblocking(fd.get())) {
    error = "cannot listen on " + address + ":" + std::to_string(port) + ": " + errno_text(errno);
    return Fd();
  }
  socklen_t len = sizeof addr;
  ::getsockname(fd.get(), reinterpret_cast<sockaddr*>(&addr), &len);
  bound_port = ntohs(addr.sin_port);
  return fd;
}

Fd accept_tcp(int listener) {
  Fd fd(::accept4(listener, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC));
  if (fd.valid()) set_nodelay(fd.get());
  return fd;
}

}  // namespace fabrik::bridges
