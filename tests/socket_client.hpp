// A marker source and pose subscriber for tests over real ZeroMQ sockets.
// ZeroMQ's PUB/SUB drops messages until a subscription has propagated, so
// handshake() sends probe frames until the first pose comes back: the test
// then knows both directions are connected (no sleeping). Every wait here
// has a deadline.
#pragma once

#include <chrono>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>
#include <zmq.hpp>

#include "config/endpoint_check.hpp"

namespace fabrik::test {

// The payload decoded (JSON or MessagePack, told apart by the first byte).
inline nlohmann::json decode_payload(const zmq::message_t& p) {
  const auto* b = static_cast<const std::uint8_t*>(p.data());
  if (p.size() > 0 && ((b[0] >= 0x80 && b[0] <= 0x8f) || b[0] == 0xde || b[0] == 0xdf))
    return nlohmann::json::from_msgpack(b, b + p.size());
  return nlohmann::json::parse(p.to_string_view());
}

// The next message of `topic` on a SUB socket (others skipped), undecoded,
// or nothing on timeout.
inline std::optional<zmq::message_t> receive_topic(zmq::socket_t& sub, const std::string& topic,
                                                   std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    // Rounded up: truncated, the last millisecond of every wait would spin without polling.
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return std::nullopt;
    zmq::pollitem_t items[] = {{sub.handle(), 0, ZMQ_POLLIN, 0}};
    zmq::poll(items, 1, left);
    if (!(items[0].revents & ZMQ_POLLIN)) continue;
    zmq::message_t t, p;
    (void)sub.recv(t);
    if (!t.more()) continue;
    (void)sub.recv(p);
    if (t.to_string_view() == topic) return p;
  }
}

// A SUB socket of `prefix` connected to `endpoint` (it drops nothing at close).
inline zmq::socket_t subscriber(zmq::context_t& context, const std::string& endpoint,
                                const char* prefix) {
  zmq::socket_t s(context, zmq::socket_type::sub);
  s.set(zmq::sockopt::linger, 0);
  s.set(zmq::sockopt::subscribe, prefix);
  s.connect(endpoint);
  return s;
}

// Receives every message waiting on `sub` without waiting; how many there were.
inline int drain(zmq::socket_t& sub) {
  int n = 0;
  zmq::message_t part;
  while (sub.recv(part, zmq::recv_flags::dontwait)) n += part.more() ? 0 : 1;
  return n;
}

class SocketClient {
 public:
  // Connects a PUB to the daemon's input and a SUB (every topic: pose, stats, model) to its
  // output.
  SocketClient(zmq::context_t& context, const std::string& input, const std::string& output)
      : pub_(context, zmq::socket_type::pub), sub_(context, zmq::socket_type::sub) {
    pub_.set(zmq::sockopt::linger, 0);
    sub_.set(zmq::sockopt::linger, 0);
    sub_.set(zmq::sockopt::subscribe, "");
    pub_.set(zmq::sockopt::ipv6, fabrik::ipv6_literal(input));
    sub_.set(zmq::sockopt::ipv6, fabrik::ipv6_literal(output));
    pub_.connect(input);
    sub_.connect(output);
  }

  void send(const std::string& payload, const std::string& topic = "markers") {
    pub_.send(zmq::buffer(topic), zmq::send_flags::sndmore);
    pub_.send(zmq::buffer(payload));
  }
  void send_parts(const std::vector<std::string>& parts) {
    std::size_t i = 0;
    for (const std::string& p : parts)
      pub_.send(zmq::buffer(p),
                ++i < parts.size() ? zmq::send_flags::sndmore : zmq::send_flags::none);
  }
  void send_frame(std::uint64_t frame, const nlohmann::json& markers = nlohmann::json::object()) {
    send(nlohmann::json{{"frame", frame}, {"units", "mm"}, {"markers", markers}}.dump());
  }

  // The next message of `topic`, undecoded, or nothing on timeout.
  std::optional<zmq::message_t> receive_raw(
      const std::string& topic,
      std::chrono::milliseconds timeout = std::chrono::milliseconds(5000)) {
    return receive_topic(sub_, topic, timeout);
  }

  // The next message of any topic, decoded, with its topic; nothing on timeout.
  std::optional<std::pair<std::string, nlohmann::json>> receive_any(
      std::chrono::milliseconds timeout = std::chrono::milliseconds(5000)) {
    zmq::pollitem_t items[] = {{sub_.handle(), 0, ZMQ_POLLIN, 0}};
    zmq::poll(items, 1, timeout);
    if (!(items[0].revents & ZMQ_POLLIN)) return std::nullopt;
    zmq::message_t t, p;
    (void)sub_.recv(t);
    if (!t.more()) return std::pair<std::string, nlohmann::json>{std::string(t.to_string_view()), nullptr};
    (void)sub_.recv(p);
    return std::pair<std::string, nlohmann::json>{std::string(t.to_string_view()), decode_payload(p)};
  }

  // The next message of `topic`, decoded (JSON or MessagePack), or nothing on
  // timeout. A payload that is not valid JSON (or UTF-8) throws.
  std::optional<nlohmann::json> receive(
      const std::string& topic,
      std::chrono::milliseconds timeout = std::chrono::milliseconds(5000)) {
    auto p = receive_raw(topic, timeout);
    if (!p) return std::nullopt;
    return decode_payload(*p);
  }

  // The first message of `topic` for which done(message) holds, or nothing after `timeout`.
  template <class Done>
  std::optional<nlohmann::json> receive_until(const std::string& topic, Done done,
                                              std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const auto left = std::chrono::ceil<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) return std::nullopt;
      auto message = receive(topic, left);
      if (message && done(*message)) return message;
    }
  }
  // The first `stats` for which done(stats) holds, or nothing after `timeout`.
  template <class Done>
  std::optional<nlohmann::json> stats_until(
      Done done, std::chrono::milliseconds timeout = std::chrono::milliseconds(5000)) {
    return receive_until("stats", done, timeout);
  }
  // The next pose of frame `frame`, skipping poses of other frames (another
  // input's, such as a vendor source's), or nothing after `timeout`.
  std::optional<nlohmann::json> pose_of(std::uint64_t frame,
                                        std::chrono::milliseconds timeout = std::chrono::milliseconds(5000)) {
    return receive_until("pose", [frame](const nlohmann::json& pose) { return pose["frame"] == frame; }, timeout);
  }

  // Probes until a pose of a probe answers (poses of other inputs' frames do
  // not count); returns the frame number after the probes.
  // Up to 600 probes, 30 s: a CI machine starved of CPU has taken over 10 s
  // to join a fresh daemon's tcp sockets. On failure the message says what
  // did come back, so a dead daemon, a dead output and a dead input differ.
  static bool is_probe(const nlohmann::json& pose, std::uint64_t probe_frame) {
    const nlohmann::json* frame = pose.is_object() && pose.contains("frame") ? &pose["frame"] : nullptr;
    return frame && frame->is_number_unsigned() && frame->get<std::uint64_t>() >= probe_frame &&
           frame->get<std::uint64_t>() < probe_frame + 1000;
  }
  std::uint64_t handshake(std::uint64_t probe_frame = 1000000) {
    int stats_seen = 0;
    nlohmann::json last_stats;
    for (int i = 0; i < 600; ++i) {
      send_frame(probe_frame + static_cast<std::uint64_t>(i));
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(50);
      for (;;) {
        const auto left = std::chrono::ceil<std::chrono::milliseconds>(
            deadline - std::chrono::steady_clock::now());
        if (left.count() <= 0) break;
        auto message = receive_any(left);
        if (!message) break;
        if (message->first == "stats") {
          ++stats_seen;
          last_stats = std::move(message->second);
        } else if (message->first == "pose" && is_probe(message->second, probe_frame)) {
          // Collect the answers to probes still in flight.
          while (receive("pose", std::chrono::milliseconds(100))) {
          }
          return probe_frame + 1000;
        }
      }
    }
    auto field = [&](const char* key) {
      return last_stats.is_object() && last_stats.contains(key) ? last_stats[key].dump() : "?";
    };
    throw std::runtime_error(
        "no pose came back from the daemon in 600 probes (" + std::to_string(stats_seen) +
        " stats came, the last with frames_in " + field("frames_in") + ", decode_errors " +
        field("decode_errors") + ", input_disconnects " + field("input_disconnects") +
        ", accept_failures " + field("accept_failures") + ", last_error " +
        field("last_error") + ")");
  }

 private:
  zmq::socket_t pub_, sub_;
};

}  // namespace fabrik::test
