// The floor `fabrik bench latency` compares the daemon with: a bare ZeroMQ
// echo on a thread of its own, in a context of its own (one I/O thread, as
// the daemon's). It binds a SUB and an XPUB with fabrikd's options, queue
// limits and kernel buffers, waits on both as the daemon's loop does, and
// answers each marker frame with a pose-sized message carrying the frame's
// number: the two hops and wake-ups of the daemon path, without the decode,
// solve and encode.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <thread>
#include <zmq.hpp>

#include "config/daemon_config.hpp"

namespace fabrik::bench {

// Where a marker frame's or a pose's frame number lies, in bytes [begin, end):
// both encoders write "frame" first (JSON `{"frame":N`; MessagePack a map
// header, the key "frame", then an unsigned integer). nullopt: neither.
struct FrameField {
  std::size_t begin = 0, end = 0;
};
std::optional<FrameField> frame_field(std::span<const std::uint8_t> message);
// The frame number itself.
std::optional<std::uint64_t> frame_number(std::span<const std::uint8_t> message);

class ZmqFloor {
 public:
  // Binds `input_address` (SUB) and `output_address` (XPUB) with the options
  // fabrikd gives its sockets under `config`. `pose` is one the daemon
  // published: each answer is that pose with the answered frame's number
  // in place of its own, so answers are the daemon's size, byte for byte
  // but the number.
  ZmqFloor(const DaemonConfig& config, const std::string& input_address,
           const std::string& output_address, std::string pose);
  ~ZmqFloor();  // stops the thread
  ZmqFloor(const ZmqFloor&) = delete;
  ZmqFloor& operator=(const ZmqFloor&) = delete;

  std::string input_endpoint() const { return input_endpoint_; }
  std::string output_endpoint() const { return output_endpoint_; }
  std::size_t pose_bytes() const { return pose_.size(); }
  std::uint64_t answered() const { return answered_.load(); }

 private:
  void run();
  void answer(const zmq::message_t& frame);

  zmq::context_t context_{1};
  zmq::socket_t sub_, pub_;
  std::string input_endpoint_, output_endpoint_;
  std::string pose_, reply_;
  FrameField pose_frame_;
  zmq::message_t topic_, payload_, extra_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> answered_{0};
  std::thread thread_;
};

}  // namespace fabrik::bench
