// The `status` message of `fabrik view`: what the input stream is doing, from what arrived
// (no sockets, so the tests feed it directly with their own clock).
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

namespace fabrik::view {

class StreamStatus {
 public:
  // `stall_after_s`: no pose for this long is "stalled"; an undecodable payload within it is
  // "garbage". `source`: what the message names ("tcp://127.0.0.1:5556").
  StreamStatus(double stall_after_s, std::string source);

  // `t_s`: arrival time on any monotonic clock.
  void add_pose(double t_s);
  void add_undecodable(double t_s, const std::string& topic, const std::string& reason);

  // {"stream": ok|waiting|stalled|garbage, "message", "poses_per_s" (since the previous
  // call), "undecodable" (in all), "clients"}.
  nlohmann::json status(double t_s, std::size_t clients);

  std::uint64_t poses() const { return poses_; }
  std::uint64_t undecodable() const { return undecodable_; }

 private:
  double stall_after_s_;
  std::string source_;
  std::uint64_t poses_ = 0, undecodable_ = 0;
  double last_pose_s_ = -1.0, last_garbage_s_ = -1.0;
  std::string last_reason_;
  std::uint64_t window_poses_ = 0, window_undecodable_ = 0;
  double window_start_s_ = -1.0;
};

}  // namespace fabrik::view
