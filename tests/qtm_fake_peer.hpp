// Hand-written QTM RT peers for tests over loopback TCP: a listener that runs
// a behaviour per connection, and the pieces of a QTM session (welcome,
// version, byte order, 3D parameters, data packets) to misbehave with. Shared
// by the client's own tests (test_qtm_client) and the daemon's
// (test_source_bad_peers). Every wait is bounded.
#pragma once

#include <catch2/catch.hpp>

#include <poll.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <stop_token>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "bridges/qtm/commands.hpp"
#include "bridges/qtm/data_packet.hpp"
#include "bridges/qtm/packet.hpp"
#include "bridges/qtm/parameters_xml.hpp"
#include "bridges/tcp.hpp"

namespace fabrik::qtm::test_peer {

using Bytes = std::vector<std::uint8_t>;

// Listens on a free loopback port and runs `behaviour` for each connection,
// one at a time, until destroyed.
class FakePeer {
 public:
  using Behaviour = std::function<void(int fd, const std::stop_token&)>;
  explicit FakePeer(Behaviour b) : behaviour_(std::move(b)) {
    std::string error;
    listener_ = bridges::listen_tcp("127.0.0.1", 0, port_, error);
    REQUIRE(listener_.valid());
    thread_ = std::jthread([this](std::stop_token st) {
      while (!st.stop_requested()) {
        if (bridges::wait_fd(listener_.get(), POLLIN, bridges::deadline_after(0.1), st) !=
            bridges::WaitResult::ready)
          continue;
        bridges::Fd fd = bridges::accept_tcp(listener_.get());
        if (!fd.valid()) continue;
        ++accepted_;
        behaviour_(fd.get(), st);
      }
    });
  }
  std::uint16_t port() const { return port_; }
  int accepted() const { return accepted_.load(); }

 private:
  Behaviour behaviour_;
  bridges::Fd listener_;
  std::uint16_t port_ = 0;
  std::atomic<int> accepted_{0};
  std::jthread thread_;
};

inline void send_bytes(int fd, const Bytes& b, const std::stop_token& st) {
  std::string error;
  bridges::send_all(fd, b, bridges::deadline_after(1.0), st, error);
}

inline Bytes string_packet(PacketType t, std::string_view s, ByteOrder o = ByteOrder::little) {
  Bytes b;
  write_string_packet(t, s, o, b);
  return b;
}

// The next command from the client, or nullopt (closed, stopped, 1 s).
inline std::optional<std::string> read_command(int fd, PacketSplitter& in, const std::stop_token& st) {
  const auto deadline = bridges::deadline_after(1.0);
  for (;;) {
    PacketView p;
    if (in.next(p) == Status::ok) {
      std::string_view s;
      if (read_string(p, PacketType::command, s) != Status::ok) return std::nullopt;
      return std::string(s);
    }
    if (bridges::wait_fd(fd, POLLIN, deadline, st) != bridges::WaitResult::ready) return std::nullopt;
    std::uint8_t buf[4096];
    const long n = bridges::read_some(fd, buf);
    if (n == 0 || n == -2) return std::nullopt;
    if (n > 0) in.feed(std::span(buf, static_cast<std::size_t>(n)));
  }
}

// Discards what the client sends until it closes or stop: a peer that says nothing more.
inline void hold(int fd, const std::stop_token& st) {
  for (;;) {
    if (bridges::wait_fd(fd, POLLIN, bridges::deadline_after(10.0), st) != bridges::WaitResult::ready) return;
    std::uint8_t buf[4096];
    const long n = bridges::read_some(fd, buf);
    if (n == 0 || n == -2) return;
  }
}

inline const std::vector<std::string> kPeerLabels = {"a", "b"};

// Plays QTM up to the StreamFrames command; false if the client went away.
inline bool handshake(int fd, const std::stop_token& st) {
  PacketSplitter in(ByteOrder::little, 1 << 16);
  send_bytes(fd, string_packet(PacketType::command, "QTM RT Interface connected"), st);
  for (;;) {
    const auto cmd = read_command(fd, in, st);
    if (!cmd) return false;
    const ParsedCommand pc = parse_command(*cmd);
    switch (pc.kind) {
      case ParsedCommand::Kind::version:
        send_bytes(fd, string_packet(PacketType::command, "Version set to 1.19"), st);
        break;
      case ParsedCommand::Kind::byte_order:
        send_bytes(fd, string_packet(PacketType::command, "Byte order is little endian"), st);
        break;
      case ParsedCommand::Kind::get_parameters: {
        Parameters3d p;
        p.labels = kPeerLabels;
        send_bytes(fd, string_packet(PacketType::xml, write_parameters_3d(p, "1.19")), st);
        break;
      }
      case ParsedCommand::Kind::stream_frames: return true;
      default: send_bytes(fd, string_packet(PacketType::error, "Parse Error"), st);
    }
  }
}

inline Bytes good_data_packet(std::uint32_t frame_number) {
  DataFrame f;
  f.timestamp_us = frame_number * 10000ull;
  f.frame_number = frame_number;
  f.has_3d = true;
  f.labelled_p_qtm_mm = {{1.f, 2.f, 3.f}, {4.f, 5.f, 6.f}};
  Bytes b;
  write_data_packet(f, ByteOrder::little, b);
  return b;
}

}  // namespace fabrik::qtm::test_peer
