// A minimal IPv4 UDP socket for the NatNet client and simulator: bind, join a
// multicast group, send to an address, wait for a datagram with a timeout.
// No exceptions: every call reports failure with a message in `error`.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace fabrik::bridges {

struct UdpEndpoint {
  std::uint32_t address_be = 0;  // network byte order, as in sockaddr_in
  std::uint16_t port = 0;        // host byte order
  friend bool operator==(const UdpEndpoint&, const UdpEndpoint&) = default;
};
std::string to_string(const UdpEndpoint& e);
// A dotted quad or a host name (first IPv4 address).
std::optional<UdpEndpoint> resolve_ipv4(const std::string& host, std::uint16_t port,
                                        std::string& error);

// The address of this host's interface that routes to `to` (what a socket
// connected to it would send from), as a dotted quad; nullopt with `error`.
std::optional<std::string> local_address_towards(const UdpEndpoint& to, std::string& error);

class UdpSocket {
 public:
  UdpSocket() = default;
  UdpSocket(UdpSocket&& other) noexcept;
  UdpSocket& operator=(UdpSocket&& other) noexcept;
  UdpSocket(const UdpSocket&) = delete;
  UdpSocket& operator=(const UdpSocket&) = delete;
  ~UdpSocket();

  // `reuse` lets several listeners share a port (multicast data port).
  bool open(const std::string& bind_address, std::uint16_t port, bool reuse, std::string& error);
  void close();
  bool is_open() const { return fd_ >= 0; }
  std::uint16_t local_port() const;

  bool join_multicast(const std::string& group, const std::string& interface_address,
                      std::string& error);
  // Outgoing multicast: which interface, and loop back to local listeners.
  bool set_multicast_sender(const std::string& interface_address, std::string& error);
  bool send_to(const UdpEndpoint& to, std::span<const std::uint8_t> bytes, std::string& error);

  enum class Received { datagram, timeout, error };
  // Waits up to timeout_ms for one datagram. `buffer` becomes its bytes;
  // `datagram_bytes` is its real length, larger than buffer.size() when it did
  // not fit in `capacity` (the rest is discarded).
  Received receive(std::vector<std::uint8_t>& buffer, std::size_t capacity, UdpEndpoint& from,
                   std::size_t& datagram_bytes, int timeout_ms, std::string& error);

  int fd() const { return fd_; }

 private:
  int fd_ = -1;
};

// Waits up to timeout_ms until one of the sockets is readable; returns its
// index, -1 on timeout or error.
int wait_readable(std::span<const UdpSocket* const> sockets, int timeout_ms);

}  // namespace fabrik::bridges
