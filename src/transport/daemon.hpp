// fabrikd's loop: marker frames in on a SUB socket, poses and stats out on a
// PUB socket (../shared/wire-contract.md, proto/). One thread does it all:
// drain what is queued, decode every frame (so bad ones are counted), solve
// the newest valid ones in order, at most `max_backlog_frames` per wake-up
// (older ones are dropped and counted: when input outpaces the solver the
// newest frames win and latency stays bounded, while a short stall of the
// thread loses nothing), publish without ever blocking (PUB drops for a slow
// subscriber), and send stats every interval.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_set>
#include <zmq.hpp>

#include "config/daemon_config.hpp"
#include "interval_stats.hpp"
#include "marker_codec.hpp"
#include "pose_codec.hpp"
#include "rate_limited_log.hpp"

namespace fabrik::wire {

struct DaemonCounters {
  std::uint64_t frames_in = 0;        // messages received on the input
  std::uint64_t frames_out = 0;       // poses published
  std::uint64_t frames_dropped = 0;   // valid frames superseded by a newer one before solving
  std::uint64_t decode_errors = 0;    // messages refused (format, types, size, parts, topic)
  std::uint64_t unknown_markers = 0;  // marker entries whose name is not in the model
  std::uint64_t reloads = 0, reload_errors = 0;
};

// Signals to the loop, set from another thread or a signal handler.
struct DaemonControl {
  std::atomic<bool> stop{false};
  std::atomic<bool> reload{false};
};

class Daemon {
 public:
  // Opens the sockets (bind or connect per config). Throws std::runtime_error
  // naming the endpoint when one cannot be opened.
  Daemon(zmq::context_t& context, DaemonConfig config);
  ~Daemon();

  // Runs until control.stop. On control.reload, calls load_config() and
  // switches to the new config; if that throws, the old one stays and the
  // error is logged.
  void run(DaemonControl& control, const std::function<DaemonConfig()>& load_config = {});

  // The endpoints as opened (a "tcp://127.0.0.1:*" bind resolves to its port).
  std::string input_endpoint() const;
  std::string output_endpoint() const;
  DaemonCounters counters() const;
  const DaemonConfig& config() const;

 private:
  struct State;  // everything that a reload replaces
  std::unique_ptr<State> make_state(DaemonConfig config, State* old);
  void drain_and_solve();
  void publish_stats(double interval_s);
  void send(const char* topic, const std::string& payload);

  zmq::context_t& context_;
  std::unique_ptr<State> state_;
  DaemonCounters counters_;
  mutable std::mutex snapshot_mutex_;  // counters() may be called from other threads
  DaemonCounters snapshot_;
  std::chrono::steady_clock::time_point started_;
  IntervalSamples solve_us_, queue_us_;
  std::uint64_t interval_frames_out_ = 0;
  std::string last_error_;
  std::unordered_set<std::string> unknown_seen_;
  RateLimitedLog bad_input_log_, send_log_;
  zmq::message_t parts_[2], extra_;
  std::string out_;
};

}  // namespace fabrik::wire
