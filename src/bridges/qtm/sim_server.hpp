// A simulated QTM RT server (TCP, protocol 1.8 and later) serving a recording
// at its own rate, for `fabrik sim qtm` and for tests over loopback. It speaks
// the protocol as docs/qtm-rt-protocol.md describes QTM: the welcome message,
// Version, QTMVersion, ByteOrder, GetState, GetParameters (General, 3D, All),
// GetCurrentFrame and StreamFrames (AllFrames, FrequencyDivisor:n,
// Frequency:n, Stop) with the 3D and 3D no labels components, events, and
// QTM's error replies to what it does not simulate. The SimScript pauses,
// drops markers, renames labels and restarts the server.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <stop_token>
#include <string>

#include "bridges/sim_recording.hpp"

namespace fabrik::qtm {

class QtmSimServer {
 public:
  struct Options {
    std::string bind_address = "127.0.0.1";
    // QTM's base port: little endian on base + 1, big endian on base + 2.
    // 0: any free pair of adjacent ports (tests).
    std::uint16_t base_port = 22222;
    // Called on the server's thread right after a frame was handed to the
    // OS (send() on every streaming client's socket), with the frame number
    // clients see and the moment just before its first send (its encoding
    // included, a microsecond); not called for a frame that went to no
    // client. For `fabrik bench latency --source qtm`, which times each frame.
    std::function<void(std::uint64_t frame_number, std::chrono::steady_clock::time_point send_start)>
        on_frame_sent;
  };
  struct Progress {
    std::uint64_t frames_sent = 0;  // frames served (the simulated measurement's clock)
    int clients = 0;                // connected clients
  };

  // Binds both ports; throws std::runtime_error saying why when it cannot, or
  // when the recording is empty or inconsistent.
  QtmSimServer(bridges::SimRecording recording, bridges::SimScript script, Options options);
  ~QtmSimServer();
  QtmSimServer(const QtmSimServer&) = delete;
  QtmSimServer& operator=(const QtmSimServer&) = delete;

  std::uint16_t port_little_endian() const;
  std::uint16_t port_big_endian() const;

  // Serves until stop, or until the script ends when not looping (the clients
  // then get a no-more-data packet and the RT From File Stopped event).
  void run(std::stop_token stop);

  Progress progress() const;  // thread-safe

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fabrik::qtm
