// A simulated OptiTrack Motive as a NatNet server (`fabrik sim natnet`, and
// the client's tests): serves a recording over NatNet's command and data
// channels as Motive streams live data.
//
// What it does, as Motive does (NatNet SDK: PacketClient.cpp, NatNetClient.py):
//   - NAT_CONNECT -> NAT_SERVERINFO ("Motive", the version pair of `version`,
//     the data port, multicast or not and the group);
//   - NAT_REQUEST_MODELDEF -> NAT_MODELDEF: one marker set named
//     SimScript::subject_prefix (or kSimMarkerSet) with the recording's marker
//     names; NatNet 3.x adds Motive 2's "all" marker set of the same markers;
//   - NAT_REQUEST "Bitstream,M.m" switches the stream's NatNet version (3.x,
//     4.x), "TimelineStop" / "TimelinePlay" pause and resume, both answered by
//     NAT_RESPONSE 0; other commands get NAT_UNRECOGNIZED_REQUEST;
//     NAT_KEEPALIVE keeps a unicast client; NAT_REQUEST_FRAMEOFDATA gets the
//     last frame; NAT_DISCONNECT drops the client;
//   - NAT_FRAMEOFDATA at rate_hz * rate_scale, one datagram per frame (NatNet
//     does not split frames: the SDK reads one frame per datagram, up to
//     PacketClient's 65503 bytes, checked in the constructor): the marker set
//     in metres, rotated from the recording's up axis into `up_axis`; the
//     labelled markers (asset 1, member = marker index + 1); frame number =
//     the script's frame index (counting on across loops), timestamp = index /
//     rate_hz (Motive keys it to the camera frame).
// Unseen markers (NaN in the recording) are (0,0,0) in the marker set and
// absent from the labelled markers; a SimScript drop is Motive's occluded
// marker: a model-solved position in the set and the occluded flag on its
// labelled marker. A rename serves new definitions and sets "tracked models
// changed" on frames until a client asks for them (at most 1 s). A restart
// closes both sockets and forgets the clients for down_seconds, then resumes
// at the same frame as a fresh server. Unicast sends each frame to every
// client (the address its NAT_CONNECT came from; clients silent for 10 s are
// dropped), multicast to group:data_port.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <stop_token>
#include <string>

#include "bridges/natnet_protocol.hpp"
#include "bridges/sim_recording.hpp"

namespace fabrik::bridges {

// The marker set's name where SimScript::subject_prefix is empty.
inline constexpr const char* kSimMarkerSet = "Subject";

class NatNetSimServer {
 public:
  struct Options {
    std::string bind_address = "127.0.0.1";
    std::uint16_t command_port = 1510;  // 0: any free port (tests)
    std::uint16_t data_port = 1511;     // 0: any free port (tests)
    bool multicast = true;
    std::string multicast_group = "239.255.42.99";
    natnet::Version version{4, 1, 0, 0};
    // What Motive's streaming "Up Axis" is: the recording (SimRecording::up)
    // is rotated into it.
    std::string up_axis = "+y";
    // Called on the server's thread right after a frame's datagram was
    // handed to the OS (sendto to the group, or to every unicast client),
    // with its frame number and the moment just before its first sendto;
    // not called for a frame that went to no client. For `fabrik bench
    // latency --source natnet`, which times each frame.
    std::function<void(std::uint64_t frame_number, std::chrono::steady_clock::time_point send_start)>
        on_frame_sent;
  };

  // Binds both sockets; throws std::runtime_error with a clear message for an
  // empty or inconsistent recording, a bad option, or a port in use.
  NatNetSimServer(SimRecording recording, SimScript script, Options options);
  ~NatNetSimServer();
  NatNetSimServer(const NatNetSimServer&) = delete;
  NatNetSimServer& operator=(const NatNetSimServer&) = delete;

  std::uint16_t command_port() const;
  std::uint16_t data_port() const;

  // Serves until stop, max_frames, or the end of a recording not looped.
  // Throws std::runtime_error only when a restart cannot bind its ports again.
  void run(std::stop_token stop);

  struct Progress {
    std::uint64_t frames_sent = 0;
    int clients = 0;
  };
  Progress progress() const;  // thread-safe

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fabrik::bridges
