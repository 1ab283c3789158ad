// `fabrik watch`: subscribes to fabrikd's `pose` and `stats`, prints a live line per stats
// interval and a summary (loss from gaps in frame numbers, residuals, solve times).
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>
#include <zmq.hpp>
#include <zmq_addon.hpp>

namespace fabrik::tools {

// Accumulates what arrives; no sockets, so the tests can feed it directly.
class WatchTally {
 public:
  // `t_s`: arrival time in seconds on any monotonic clock.
  void add_pose(const nlohmann::json& pose, double t_s);
  void add_stats(const nlohmann::json& stats, double t_s);
  void add_undecodable() { ++undecodable_; }
  // A message under a longer topic than the one watched (`pose/Alice` while watching `pose`):
  // counted to name in the summary, at most 32 topics.
  void add_other_topic(std::string_view topic);
  // One compact line over what arrived since the previous call.
  std::string live_line(double t_s);
  nlohmann::json summary() const;
  std::string summary_text() const;
  std::uint64_t poses() const { return poses_; }

 private:
  struct Interval {
    std::uint64_t poses = 0;
    std::uint64_t fitted = 0;  // poses with a residual: a measured marker (residual.count > 0)
    double rms_sum = 0.0, max = 0.0, occluded_sum = 0.0;
    std::map<std::string, std::uint64_t> status;
    double start_s = -1.0;
  };
  std::uint64_t poses_ = 0, stats_count_ = 0, undecodable_ = 0, malformed_ = 0;
  std::uint64_t missing_frames_ = 0, gap_events_ = 0, restarts_ = 0, repeats_ = 0;
  std::optional<std::uint64_t> first_frame_, last_frame_;
  double first_t_s_ = -1.0, last_t_s_ = -1.0;
  double rms_sum_ = 0.0, residual_max_ = 0.0, occluded_sum_ = 0.0;
  std::uint64_t fitted_ = 0;  // poses with a residual (residual.count > 0)
  std::string units_;
  std::map<std::string, std::uint64_t> status_, stop_, other_topics_;
  std::vector<double> solve_us_, latency_us_;
  std::optional<nlohmann::json> last_stats_;
  nlohmann::json last_angles_;  // the latest pose's `angles` (degrees), if it had any
  Interval interval_;
};

struct WatchOptions {
  std::string endpoint;
  bool bind = false;     // default: connect (fabrikd binds its output)
  double seconds = 0.0;  // 0: until stop_requested
  // The poses' topic: `pose`, a subject's `pose/NAME`, or a view's (config output.views).
  std::string topic = "pose";
  std::function<bool()> stop_requested;
  std::function<void(const std::string&)> live;  // one line per stats interval
};

// Runs until `seconds` elapse or stop_requested(); returns the tally's summary.
nlohmann::json watch(zmq::context_t& context, const WatchOptions& options, WatchTally& tally);

}  // namespace fabrik::tools
