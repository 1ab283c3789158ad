#include "stream_status.hpp"

#include <algorithm>
#include <cstdio>

#include "common/safe_text.hpp"

namespace fabrik::view {

StreamStatus::StreamStatus(double stall_after_s, std::string source)
    : stall_after_s_(stall_after_s), source_(std::move(source)) {}

void StreamStatus::add_pose(double t_s) {
  ++poses_;
  last_pose_s_ = t_s;
}

void StreamStatus::add_undecodable(double t_s, const std::string& topic,
                                   const std::string& reason) {
  ++undecodable_;
  last_garbage_s_ = t_s;
  // A hostile payload's bytes may be quoted in the reason: cut and made printable.
  std::string r = reason.size() > 200 ? reason.substr(0, 200) + "..." : reason;
  last_reason_ = "topic " + safe_lines(topic.substr(0, 32)) + ": " + safe_lines(r);
}

namespace {
// A fabrikd has a few subjects; a flood of topics must not grow the message without bound.
constexpr std::size_t kMaxSubjects = 16;
constexpr std::size_t kMaxSubjectChars = 64;
}  // namespace

bool StreamStatus::add_other_subject(const std::string& name) {
  const std::string safe = safe_lines(name.substr(0, kMaxSubjectChars));
  if (other_subjects_.size() >= kMaxSubjects ||
      std::find(other_subjects_.begin(), other_subjects_.end(), safe) != other_subjects_.end())
    return false;
  other_subjects_.push_back(safe);
  return true;
}

std::string StreamStatus::subjects_hint() const {
  if (other_subjects_.empty()) return "";
  std::string names;
  for (const std::string& n : other_subjects_) names += (names.empty() ? "" : ", ") + n;
  return "poses arrive for subjects " + names +
         " (a multi-subject fabrikd), none on 'pose': " + "start fabrik view with --subject " +
         other_subjects_.front();
}

nlohmann::json StreamStatus::status(double t_s, std::size_t clients) {
  if (window_start_s_ < 0.0) window_start_s_ = t_s;
  const double span_s = t_s - window_start_s_;
  const double rate = span_s > 0.0 ? static_cast<double>(poses_ - window_poses_) / span_s : 0.0;
  const std::uint64_t garbage_in_window = undecodable_ - window_undecodable_;
  if (span_s > 0.0) {
    window_start_s_ = t_s;
    window_poses_ = poses_;
    window_undecodable_ = undecodable_;
  }
  std::string stream, message;
  char buf[160];
  if (last_garbage_s_ >= 0.0 && t_s - last_garbage_s_ <= stall_after_s_) {
    stream = "garbage";
    std::snprintf(buf, sizeof buf, "undecodable payloads (%llu in all, %llu lately)",
                  static_cast<unsigned long long>(undecodable_),
                  static_cast<unsigned long long>(garbage_in_window));
    message = std::string(buf) + ": " + last_reason_;
  } else if (last_pose_s_ < 0.0) {
    stream = "waiting";
    message = other_subjects_.empty() ? "waiting for poses from " + source_ : subjects_hint();
  } else if (t_s - last_pose_s_ > stall_after_s_) {
    stream = "stalled";
    std::snprintf(buf, sizeof buf, "no pose for %.1f s from ", t_s - last_pose_s_);
    message = buf + source_;
  } else {
    stream = "ok";
    message = "poses from " + source_;
  }
  nlohmann::json out = {{"stream", stream},
                        {"message", message},
                        {"poses_per_s", rate},
                        {"undecodable", undecodable_},
                        {"clients", clients}};
  if (stream == "waiting" && !other_subjects_.empty()) out["subjects"] = other_subjects_;
  return out;
}

}  // namespace fabrik::view
