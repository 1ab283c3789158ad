#include "watch.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "common/quantile.hpp"
#include "common/safe_text.hpp"
#include "wire.hpp"

namespace fabrik::tools {

using nlohmann::json;

namespace {

double number_at(const json& doc, const json::json_pointer& p, double fallback = NAN) {
  if (!doc.contains(p)) return fallback;
  const json& v = doc.at(p);
  return v.is_number() ? v.get<double>() : fallback;
}

// The angles a live line shows: these when the model has them (gait analysts
// look at the sagittal angles first), else the pose's first four.
std::string angles_text(const json& angles) {
  if (!angles.is_object() || angles.empty()) return "";
  static const char* const kPreferred[] = {"hip_flexion_r", "knee_angle_r", "ankle_angle_r",
                                           "hip_flexion_l", "knee_angle_l", "ankle_angle_l"};
  std::vector<std::string> names;
  for (const char* n : kPreferred)
    if (angles.contains(n)) names.emplace_back(n);
  if (names.empty())
    for (auto it = angles.begin(); names.size() < 4 && it != angles.end(); ++it)
      names.push_back(it.key());
  std::string s = "  | deg";
  char buf[96];
  for (const std::string& n : names) {
    const json& v = angles[n];
    if (!v.is_number()) continue;
    std::snprintf(buf, sizeof buf, " %s %.1f", n.c_str(), v.get<double>());
    s += buf;
  }
  return s;
}

std::string status_text(const std::map<std::string, std::uint64_t>& status) {
  std::string s;
  for (const auto& [name, n] : status) s += " " + safe_text(name) + " " + std::to_string(n);
  return s;
}

// A count per name a peer sends, at most 32 names: a stream of new words cannot grow it.
void count_name(std::map<std::string, std::uint64_t>& counts, const std::string& name) {
  if (counts.size() < 32 || counts.contains(name)) ++counts[name];
}

}  // namespace

void WatchTally::add_other_topic(std::string_view topic) {
  count_name(other_topics_, std::string(topic));
}

void WatchTally::add_pose(const json& pose, double t_s) {
  if (!pose.is_object() || !pose.contains("frame") || !pose["frame"].is_number_unsigned()) {
    ++malformed_;
    return;
  }
  const auto frame = pose["frame"].get<std::uint64_t>();
  if (last_frame_) {
    if (frame > *last_frame_ + 1) {
      missing_frames_ += frame - *last_frame_ - 1;
      ++gap_events_;
    } else if (frame == *last_frame_) {
      ++repeats_;
    } else if (frame < *last_frame_) {
      ++restarts_;  // the contract allows a source to restart its numbering
    }
  } else {
    first_frame_ = frame;
    first_t_s_ = t_s;
  }
  last_frame_ = frame;
  last_t_s_ = t_s;
  ++poses_;
  if (pose.contains("units") && pose["units"].is_string()) units_ = pose["units"];
  const double rms = number_at(pose, "/residual/rms"_json_pointer, 0.0);
  const double max = number_at(pose, "/residual/max"_json_pointer, 0.0);
  // A pose without a measured marker (an IMU-only stream, a subject out of the volume) has no
  // residual: its 0 is not a perfect fit. A pose without a count is taken as fitted.
  const double residual_count = number_at(pose, "/residual/count"_json_pointer, 1.0);
  const bool fitted = !(residual_count == 0.0);
  const double occluded = pose.contains("occluded") && pose["occluded"].is_array()
                              ? static_cast<double>(pose["occluded"].size())
                              : 0.0;
  std::string status = "unknown";
  if (pose.contains("/solver/status"_json_pointer) && pose["solver"]["status"].is_string())
    status = pose["solver"]["status"];
  // The contract's status says converged for a stalled solve: the stop says how it ended.
  if (pose.contains("/solver/stop"_json_pointer) && pose["solver"]["stop"].is_string())
    count_name(stop_, pose["solver"]["stop"].get<std::string>());
  const double solve_us = number_at(pose, "/solver/solve_us"_json_pointer);
  if (std::isfinite(solve_us)) solve_us_.push_back(solve_us);
  // End to end, from the source's send to now: the pose echoes the frame's
  // stamp_us (a wall clock, so only meaningful with source and watcher on one machine).
  const double stamp_us = number_at(pose, "/stamp_us"_json_pointer);
  if (std::isfinite(stamp_us)) {
    const double now_us =
        static_cast<double>(std::chrono::duration_cast<std::chrono::microseconds>(
                                std::chrono::system_clock::now().time_since_epoch())
                                .count());
    latency_us_.push_back(now_us - stamp_us);
  }

  if (pose.contains("angles") && pose["angles"].is_object()) last_angles_ = pose["angles"];
  if (fitted) {
    ++fitted_;
    rms_sum_ += rms;
    residual_max_ = std::max(residual_max_, max);
  }
  occluded_sum_ += occluded;
  count_name(status_, status);
  if (interval_.start_s < 0.0) interval_.start_s = t_s;
  ++interval_.poses;
  if (fitted) {
    ++interval_.fitted;
    interval_.rms_sum += rms;
    interval_.max = std::max(interval_.max, max);
  }
  interval_.occluded_sum += occluded;
  count_name(interval_.status, status);
}

void WatchTally::add_stats(const json& stats, double) {
  ++stats_count_;
  last_stats_ = stats;
}

namespace {

// A vendor source's connection, when the daemon reads one: what a lab looks
// at first when poses stop.
std::string source_text(const json& stats) {
  const auto it = stats.find("source");
  if (it == stats.end() || !it->is_object()) return "";
  const json& s = *it;
  const auto uint_at = [&](const char* key) -> std::uint64_t {
    const auto v = s.find(key);
    return v != s.end() && v->is_number_integer() ? static_cast<std::uint64_t>(std::max<std::int64_t>(v->get<std::int64_t>(), 0)) : 0;
  };
  std::string text = "  | source " + std::string(s.value("connected", false) ? "connected" : "NOT connected");
  text += " (" + std::to_string(uint_at("frames")) + " frames, " + std::to_string(uint_at("reconnects")) +
          " reconnects, " + std::to_string(uint_at("errors")) + " errors";
  if (const auto bad = uint_at("bad_packets")) text += ", " + std::to_string(bad) + " bad packets";
  text += ")";
  if (!s.value("connected", false) && s.contains("last_error") && s["last_error"].is_string())
    text += ": " + s["last_error"].get<std::string>();
  return text;
}

}  // namespace

std::string WatchTally::live_line(double t_s) {
  const Interval& in = interval_;
  const double span_s = in.start_s >= 0.0 ? t_s - in.start_s : 0.0;
  const double n = static_cast<double>(std::max<std::uint64_t>(in.poses, 1));
  char buf[512];
  char residual[96];
  if (in.fitted > 0)
    std::snprintf(residual, sizeof residual, "rms %.3f max %.3f %s",
                  in.rms_sum / static_cast<double>(in.fitted), in.max,
                  units_.empty() ? "" : units_.c_str());
  else if (in.poses == 0)
    std::snprintf(residual, sizeof residual, "rms none (no pose this interval)");
  else
    std::snprintf(residual, sizeof residual, "rms none (no marker measured)");
  std::snprintf(buf, sizeof buf, "%6.1f Hz  frame %-8llu %s  occluded %.1f  |",
                span_s > 0.0 ? static_cast<double>(in.poses) / span_s : 0.0,
                static_cast<unsigned long long>(last_frame_.value_or(0)), residual,
                in.occluded_sum / n);
  std::string line = buf;
  line += status_text(in.status);
  if (last_stats_) {
    std::snprintf(buf, sizeof buf,
                  "  | solve p50 %.1f p99 %.1f us  queue p50 %.0f p99 %.0f us  decode_errors %.0f",
                  number_at(*last_stats_, "/solve_us/p50"_json_pointer),
                  number_at(*last_stats_, "/solve_us/p99"_json_pointer),
                  number_at(*last_stats_, "/queue_latency_us/p50"_json_pointer),
                  number_at(*last_stats_, "/queue_latency_us/p99"_json_pointer),
                  number_at(*last_stats_, "/decode_errors"_json_pointer));
    line += buf;
    line += source_text(*last_stats_);
  }
  line += angles_text(last_angles_);
  if (missing_frames_) line += "  | lost " + std::to_string(missing_frames_);
  interval_ = Interval{};
  interval_.start_s = t_s;
  return line;
}

json WatchTally::summary() const {
  const double n = static_cast<double>(std::max<std::uint64_t>(poses_, 1));
  const double span_s = last_t_s_ - first_t_s_;
  const double expected = last_frame_ ? static_cast<double>(poses_ + missing_frames_) : 0.0;
  json s;
  s["poses"] = poses_;
  s["stats_messages"] = stats_count_;
  s["undecodable"] = undecodable_;
  s["malformed"] = malformed_;
  s["first_frame"] = first_frame_ ? json(*first_frame_) : json(nullptr);
  s["last_frame"] = last_frame_ ? json(*last_frame_) : json(nullptr);
  s["missing_frames"] = missing_frames_;
  s["gap_events"] = gap_events_;
  s["restarts"] = restarts_;
  s["repeats"] = repeats_;
  s["loss_ratio"] = expected > 0.0 ? static_cast<double>(missing_frames_) / expected : 0.0;
  s["pose_rate_hz"] = poses_ > 1 && span_s > 0.0 ? static_cast<double>(poses_ - 1) / span_s : 0.0;
  s["units"] = units_.empty() ? json(nullptr) : json(units_);
  // Over the poses with a measured marker; null when none had one.
  s["residual"] = {
      {"rms_mean", fitted_ > 0 ? json(rms_sum_ / static_cast<double>(fitted_)) : json(nullptr)},
      {"max", fitted_ > 0 ? json(residual_max_) : json(nullptr)},
      {"poses", fitted_}};
  s["occluded_mean"] = occluded_sum_ / n;
  s["status"] = status_;
  s["stop"] = stop_;
  s["other_topics"] = other_topics_;
  s["solve_us"] = {{"p50", quantile(solve_us_, 0.5)},
                   {"p99", quantile(solve_us_, 0.99)},
                   {"max", quantile(solve_us_, 1.0)}};
  if (!latency_us_.empty())
    s["latency_us"] = {{"p50", quantile(latency_us_, 0.5)}, {"p99", quantile(latency_us_, 0.99)}};
  s["last_stats"] = last_stats_ ? *last_stats_ : json(nullptr);
  return s;
}

std::string WatchTally::summary_text() const {
  const json s = summary();
  if (poses_ == 0) {  // nothing to measure: say so rather than null frames and zero residuals
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "poses 0: no pose received; stats messages %llu, undecodable %llu\n",
                  static_cast<unsigned long long>(stats_count_),
                  static_cast<unsigned long long>(undecodable_));
    std::string text = buf;
    if (!other_topics_.empty()) {  // a multi-subject daemon: one topic per subject, no `pose`
      text += "poses arrived on";
      for (const auto& [topic, n] : other_topics_)
        text += " " + safe_text(topic) + " (" + std::to_string(n) + ")";
      text +=
          ": one topic per subject. Fix: --topic " + safe_text(other_topics_.begin()->first) + "\n";
    }
    return text;
  }
  char residual[160];
  if (fitted_ > 0)
    std::snprintf(residual, sizeof residual, "residual rms mean %.3f, max %.3f %s",
                  rms_sum_ / static_cast<double>(fitted_), residual_max_, units_.c_str());
  else
    std::snprintf(residual, sizeof residual, "residual none: no pose had a measured marker");
  char buf[1024];
  std::snprintf(
      buf, sizeof buf,
      "poses %llu (frames %s..%s), %llu missing in %llu gaps (%.3f%% loss), %llu restarts\n"
      "%s; occluded %.2f markers per frame\n"
      "solve_us p50 %.2f p99 %.2f max %.2f; stats messages %llu, undecodable %llu\nstatus:%s\n",
      static_cast<unsigned long long>(poses_), s["first_frame"].dump().c_str(),
      s["last_frame"].dump().c_str(), static_cast<unsigned long long>(missing_frames_),
      static_cast<unsigned long long>(gap_events_), 100.0 * s["loss_ratio"].get<double>(),
      static_cast<unsigned long long>(restarts_), residual, s["occluded_mean"].get<double>(),
      s["solve_us"]["p50"].get<double>(), s["solve_us"]["p99"].get<double>(),
      s["solve_us"]["max"].get<double>(), static_cast<unsigned long long>(stats_count_),
      static_cast<unsigned long long>(undecodable_), status_text(status_).c_str());
  std::string text = buf;
  if (!stop_.empty() && text.ends_with('\n'))
    text.insert(text.size() - 1, " (solver stop:" + status_text(stop_) + ")");
  return text;
}

json watch(zmq::context_t& context, const WatchOptions& options, WatchTally& tally) {
  using Clock = std::chrono::steady_clock;
  zmq::socket_t sub(context, zmq::socket_type::sub);
  sub.set(zmq::sockopt::linger, 0);
  sub.set(zmq::sockopt::rcvhwm, 100000);
  sub.set(zmq::sockopt::subscribe, options.topic);
  sub.set(zmq::sockopt::subscribe, "stats");
  open_endpoint(sub, options.endpoint, options.bind, "--from");

  const Clock::time_point start = Clock::now();
  const auto secs = [&](Clock::time_point t) {
    return std::chrono::duration<double>(t - start).count();
  };
  Clock::time_point last_line = start;
  std::vector<zmq::message_t> parts;
  for (;;) {
    const Clock::time_point now = Clock::now();
    if (options.stop_requested && options.stop_requested()) break;
    if (options.seconds > 0.0 && secs(now) >= options.seconds) break;
    // Without stats (an old or stalled daemon) still print a line per second.
    if (options.live && now - last_line > std::chrono::milliseconds(1500)) {
      options.live(tally.live_line(secs(now)) + "  (no stats)");
      last_line = now;
    }
    if (!wait_readable(sub, std::chrono::milliseconds(100))) continue;
    parts.clear();
    zmq::message_t part;
    if (!receive_waiting(sub, part)) continue;
    // A message's parts arrive together: the rest is there, whatever a signal interrupts.
    parts.push_back(std::move(part));
    while (parts.back().more()) {
      receive_part(sub, part);
      parts.push_back(std::move(part));
    }
    const double t_s = secs(Clock::now());
    if (parts.size() != 2) {
      tally.add_undecodable();
      continue;
    }
    json doc;
    try {
      doc = decode_payload(parts[1].to_string_view());
    } catch (const std::exception&) {
      tally.add_undecodable();
      continue;
    }
    const std::string_view topic = parts[0].to_string_view();
    if (topic == options.topic) {  // exactly: a subscription also takes longer topics
      tally.add_pose(doc, t_s);
    } else if (topic.size() > options.topic.size() && topic.starts_with(options.topic) &&
               topic[options.topic.size()] == '/') {
      tally.add_other_topic(topic);
    } else if (topic == "stats") {
      tally.add_stats(doc, t_s);
      if (options.live) options.live(tally.live_line(t_s));
      last_line = Clock::now();
    }
  }
  json s = tally.summary();
  s["endpoint"] = options.endpoint;
  s["seconds"] = secs(Clock::now());
  return s;
}

}  // namespace fabrik::tools
