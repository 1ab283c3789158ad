#include "zmq_floor.hpp"

#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <string_view>

#include "transport/socket_options.hpp"

namespace fabrik::bench {

namespace {

// MessagePack's unsigned integers: a positive fixint is its own byte.
std::size_t msgpack_uint_bytes(std::uint8_t tag) {
  if (tag < 0x80) return 1;
  return tag == 0xcc ? 2 : tag == 0xcd ? 3 : tag == 0xce ? 5 : tag == 0xcf ? 9 : 0;
}

}  // namespace

std::optional<FrameField> frame_field(std::span<const std::uint8_t> m) {
  constexpr std::string_view json_prefix = "{\"frame\":";
  const std::string_view text(reinterpret_cast<const char*>(m.data()), m.size());
  if (text.starts_with(json_prefix)) {
    const std::size_t begin = json_prefix.size();
    std::size_t end = begin;
    while (end < m.size() && m[end] >= '0' && m[end] <= '9') ++end;
    if (end == begin) return std::nullopt;
    return FrameField{begin, end};
  }
  if (m.empty()) return std::nullopt;
  const std::size_t header = (m[0] & 0xf0) == 0x80 ? 1 : m[0] == 0xde ? 3 : m[0] == 0xdf ? 5 : 0;
  if (header == 0 || m.size() < header + 7 || m[header] != 0xa5 ||
      std::memcmp(m.data() + header + 1, "frame", 5) != 0)
    return std::nullopt;
  const std::size_t begin = header + 6;
  const std::size_t n = msgpack_uint_bytes(m[begin]);
  if (n == 0 || begin + n > m.size()) return std::nullopt;
  return FrameField{begin, begin + n};
}

std::optional<std::uint64_t> frame_number(std::span<const std::uint8_t> m) {
  const std::optional<FrameField> f = frame_field(m);
  if (!f) return std::nullopt;
  std::uint64_t v = 0;
  if (m[0] == '{') {
    for (std::size_t i = f->begin; i < f->end; ++i) v = v * 10 + (m[i] - '0');
    return v;
  }
  if (f->end - f->begin == 1) return m[f->begin];
  for (std::size_t i = f->begin + 1; i < f->end; ++i) v = (v << 8) | m[i];
  return v;
}

ZmqFloor::ZmqFloor(const DaemonConfig& config, const std::string& input_address,
                   const std::string& output_address, std::string pose)
    : sub_(context_, zmq::socket_type::sub),
      pub_(context_, zmq::socket_type::xpub),
      pose_(std::move(pose)) {
  const std::optional<FrameField> f =
      frame_field({reinterpret_cast<const std::uint8_t*>(pose_.data()), pose_.size()});
  if (!f) throw std::invalid_argument("the floor's pose has no frame number where poses have it");
  pose_frame_ = *f;
  reply_.reserve(pose_.size() + 16);
  // fabrikd's input and output sockets, by the daemon's own rules.
  wire::set_input_options(sub_, config);
  wire::set_output_options(pub_, config);
  sub_.bind(input_address);
  pub_.bind(output_address);
  input_endpoint_ = sub_.get(zmq::sockopt::last_endpoint);
  output_endpoint_ = pub_.get(zmq::sockopt::last_endpoint);
  thread_ = std::thread([this] { run(); });
}

ZmqFloor::~ZmqFloor() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void ZmqFloor::run() {
  zmq::pollitem_t items[] = {{sub_.handle(), 0, ZMQ_POLLIN, 0}, {pub_.handle(), 0, ZMQ_POLLIN, 0}};
  while (!stop_.load()) {
    // As the daemon's loop: wake for input or subscriptions, and at least
    // every 100 ms to see a stop.
    try {
      zmq::poll(items, 2, std::chrono::milliseconds(100));
    } catch (const zmq::error_t& e) {
      if (e.num() == EINTR) continue;  // a signal: look at the flag
      throw;
    }
    if (items[0].revents & ZMQ_POLLIN) {
      // Drain what is queued, answering each frame in turn.
      while (sub_.recv(topic_, zmq::recv_flags::dontwait)) {
        int parts = 1;
        for (bool more = topic_.more(); more; ++parts) {
          zmq::message_t& m = parts == 1 ? payload_ : extra_;
          if (!sub_.recv(m, zmq::recv_flags::dontwait)) break;
          more = m.more();
        }
        if (parts == 2) answer(payload_);
      }
    }
    // Subscriptions come to the loop too (XPUB_VERBOSER): taken and let be.
    if (items[1].revents & ZMQ_POLLIN)
      while (pub_.recv(extra_, zmq::recv_flags::dontwait)) {
      }
  }
}

void ZmqFloor::answer(const zmq::message_t& frame) {
  const auto* b = static_cast<const std::uint8_t*>(frame.data());
  const std::optional<FrameField> f = frame_field({b, frame.size()});
  if (!f) return;
  // The daemon's pose with this frame's number: the encoders write a frame
  // number the same way in marker frames and poses.
  reply_.assign(pose_, 0, pose_frame_.begin);
  reply_.append(reinterpret_cast<const char*>(b) + f->begin, f->end - f->begin);
  reply_.append(pose_, pose_frame_.end);
  // The daemon's send, step by step: ZMQ_EVENTS read first, then topic and
  // payload without blocking.
  (void)pub_.get(zmq::sockopt::events);
  pub_.send(zmq::buffer(std::string_view("pose")),
            zmq::send_flags::sndmore | zmq::send_flags::dontwait);
  pub_.send(zmq::buffer(reply_), zmq::send_flags::dontwait);
  ++answered_;
}

}  // namespace fabrik::bench
