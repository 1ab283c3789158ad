// The `status` message of `fabrik view`: what the input stream is doing, from what arrived
// (no sockets, so the tests feed it directly with their own clock).
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fabrik::view {

class StreamStatus {
 public:
  // `stall_after_s`: no pose for this long is "stalled"; an undecodable payload within it is
  // "garbage". `source`: what the message names ("tcp://127.0.0.1:5556").
  StreamStatus(double stall_after_s, std::string source);

  // `t_s`: arrival time on any monotonic clock.
  void add_pose(double t_s);
  void add_undecodable(double t_s, const std::string& topic, const std::string& reason);
  // A pose on `pose/NAME` while the view waits on plain `pose` (a multi-subject fabrikd):
  // the waiting message names the subjects and --subject. Returns whether NAME is new.
  bool add_other_subject(const std::string& name);

  // {"stream": ok|waiting|stalled|garbage, "message", "poses_per_s" (since the previous
  // call), "undecodable" (in all), "clients"}, and "subjects" (the names of add_other_subject)
  // while waiting with some.
  nlohmann::json status(double t_s, std::size_t clients);

  // The waiting message for the subjects seen (empty when none).
  std::string subjects_hint() const;

  std::uint64_t poses() const { return poses_; }
  std::uint64_t undecodable() const { return undecodable_; }

 private:
  double stall_after_s_;
  std::string source_;
  std::uint64_t poses_ = 0, undecodable_ = 0;
  double last_pose_s_ = -1.0, last_garbage_s_ = -1.0;
  std::string last_reason_;
  std::vector<std::string> other_subjects_;  // in order of arrival, at most kMaxSubjects
  std::uint64_t window_poses_ = 0, window_undecodable_ = 0;
  double window_start_s_ = -1.0;
};

}  // namespace fabrik::view
