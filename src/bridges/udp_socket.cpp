#include "bridges/udp_socket.hpp"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>

namespace fabrik::bridges {

namespace {

std::string errno_text(const char* what) { return std::string(what) + ": " + std::strerror(errno); }

bool parse_ipv4(const std::string& text, in_addr& out) {
  return inet_pton(AF_INET, text.c_str(), &out) == 1;
}

}  // namespace

std::string to_string(const UdpEndpoint& e) {
  in_addr a{};
  a.s_addr = e.address_be;
  std::array<char, INET_ADDRSTRLEN> text{};
  inet_ntop(AF_INET, &a, text.data(), text.size());
  return std::string(text.data()) + ":" + std::to_string(e.port);
}

std::optional<UdpEndpoint> resolve_ipv4(const std::string& host, std::uint16_t port,
                                        std::string& error) {
  in_addr a{};
  if (parse_ipv4(host, a)) return UdpEndpoint{a.s_addr, port};
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  const int rc = getaddrinfo(host.c_str(), nullptr, &hints, &found);
  if (rc != 0 || found == nullptr) {
    error = "cannot resolve host '" + host + "': " + gai_strerror(rc);
    return std::nullopt;
  }
  UdpEndpoint e{reinterpret_cast<const sockaddr_in*>(found->ai_addr)->sin_addr.s_addr, port};
  freeaddrinfo(found);
  return e;
}

std::optional<std::string> local_address_towards(const UdpEndpoint& to, std::string& error) {
  // connect() on a datagram socket only chooses the route: nothing is sent.
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    error = errno_text("socket");
    return std::nullopt;
  }
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = to.address_be;
  addr.sin_port = htons(to.port == 0 ? 9 : to.port);
  sockaddr_in local{};
  socklen_t len = sizeof local;
  std::optional<std::string> found;
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&local), &len) != 0) {
    error = errno_text(("no route to " + to_string(to)).c_str());
  } else {
    char text[INET_ADDRSTRLEN] = {};
    if (inet_ntop(AF_INET, &local.sin_addr, text, sizeof text)) found = text;
    else error = errno_text("inet_ntop");
  }
  ::close(fd);
  return found;
}

UdpSocket::UdpSocket(UdpSocket&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }
UdpSocket& UdpSocket::operator=(UdpSocket&& other) noexcept {
  if (this != &other) {
    close();
    fd_ = other.fd_;
    other.fd_ = -1;
  }
  return *this;
}
UdpSocket::~UdpSocket() { close(); }

void UdpSocket::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

bool UdpSocket::open(const std::string& bind_address, std::uint16_t port, bool reuse,
                     std::string& error) {
  close();
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  if (!parse_ipv4(bind_address, addr.sin_addr)) {
    error = "'" + bind_address + "' is not an IPv4 address to bind to";
    return false;
  }
  fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, IPPROTO_UDP);
  if (fd_ < 0) {
    error = errno_text("socket");
    return false;
  }
  const int one = 1;
  if (reuse) setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  // Room for bursts of frames while the reader is busy (Motive's clients ask for ~1 MB).
  const int rcvbuf = 1 << 20;
  setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
  if (::bind(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    error = errno_text(("bind " + bind_address + ":" + std::to_string(port)).c_str());
    close();
    return false;
  }
  return true;
}

std::uint16_t UdpSocket::local_port() const {
  sockaddr_in addr{};
  socklen_t len = sizeof addr;
  if (fd_ < 0 || getsockname(fd_, reinterpret_cast<sockaddr*>(&addr), &len) != 0) return 0;
  return ntohs(addr.sin_port);
}

bool UdpSocket::join_multicast(const std::string& group, const std::string& interface_address,
                               std::string& error) {
  ip_mreq m{};
  if (!parse_ipv4(group, m.imr_multiaddr) || !parse_ipv4(interface_address, m.imr_interface)) {
    error = "multicast group '" + group + "' or interface '" + interface_address +
            "' is not an IPv4 address";
    return false;
  }
  if (setsockopt(fd_, IPPROTO_IP, IP_ADD_MEMBERSHIP, &m, sizeof m) != 0) {
    error = errno_text(("join multicast group " + group + " on " + interface_address).c_str());
    return false;
  }
  return true;
}

bool UdpSocket::set_multicast_sender(const std::string& interface_address, std::string& error) {
  in_addr a{};
  if (!parse_ipv4(interface_address, a)) {
    error = "'" + interface_address + "' is not an IPv4 interface address";
    return false;
  }
  const unsigned char loop = 1;
  if (setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_IF, &a, sizeof a) != 0 ||
      setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof loop) != 0) {
    error = errno_text(("multicast sender on " + interface_address).c_str());
    return false;
  }
  return true;
}

bool UdpSocket::send_to(const UdpEndpoint& to, std::span<const std::uint8_t> bytes,
                        std::string& error) {
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(to.port);
  addr.sin_addr.s_addr = to.address_be;
  const auto sent = ::sendto(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL,
                             reinterpret_cast<const sockaddr*>(&addr), sizeof addr);
  if (sent != static_cast<ssize_t>(bytes.size())) {
    error = errno_text(("send to " + to_string(to)).c_str());
    return false;
  }
  return true;
}

UdpSocket::Received UdpSocket::receive(std::vector<std::uint8_t>& buffer, std::size_t capacity,
                                       UdpEndpoint& from, std::size_t& datagram_bytes,
                                       int timeout_ms, std::string& error) {
  pollfd p{fd_, POLLIN, 0};
  const int ready = ::poll(&p, 1, timeout_ms);
  if (ready == 0 || (ready < 0 && errno == EINTR)) return Received::timeout;
  if (ready < 0) {
    error = errno_text("poll");
    return Received::error;
  }
  buffer.resize(capacity);
  sockaddr_in addr{};
  socklen_t len = sizeof addr;
  // MSG_TRUNC: the return value is the datagram's real length even when it
  // did not fit, so an oversized datagram is seen as such, not cut silently.
  const auto n = ::recvfrom(fd_, buffer.data(), buffer.size(), MSG_TRUNC | MSG_DONTWAIT,
                            reinterpret_cast<sockaddr*>(&addr), &len);
  if (n < 0) {
    buffer.clear();
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return Received::timeout;
    error = errno_text("receive");
    return Received::error;
  }
  datagram_bytes = static_cast<std::size_t>(n);
  buffer.resize(std::min(datagram_bytes, capacity));
  from = UdpEndpoint{addr.sin_addr.s_addr, ntohs(addr.sin_port)};
  return Received::datagram;
}

int wait_readable(std::span<const UdpSocket* const> sockets, int timeout_ms) {
  std::array<pollfd, 4> fds{};
  const std::size_t n = std::min(sockets.size(), fds.size());
  for (std::size_t i = 0; i < n; ++i) fds[i] = pollfd{sockets[i]->fd(), POLLIN, 0};
  const int ready = ::poll(fds.data(), n, timeout_ms);
  if (ready <= 0) return -1;
  for (std::size_t i = 0; i < n; ++i)
    if ((fds[i].revents & (POLLIN | POLLERR)) != 0) return static_cast<int>(i);
  return -1;
}

}  // namespace fabrik::bridges
