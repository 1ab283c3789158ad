// A vendor source (QTM, NatNet) inside fabrikd: its client runs on a thread
// of its own and hands each frame, as a `markers` message (SourceFrames),
// to the daemon's loop over an inproc PUSH/PULL pair. The loop drains that
// socket exactly as it drains the ZeroMQ input, so a source's frames are
// validated, queued, dropped under overload and counted the same way.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <stop_token>
#include <string>
#include <thread>
#include <vector>
#include <zmq.hpp>

#include "bridges/source.hpp"
#include "config/source_config.hpp"
#include "rate_limited_log.hpp"
#include "solver/model.hpp"

namespace fabrik::wire {

// Runs a vendor protocol until stop is requested (never throws).
using SourceClient =
    std::function<void(bridges::FrameSink&, bridges::SourceStatus&, std::stop_token)>;

// The client for a config's source (QTM or NatNet), its options taken from the config.
SourceClient make_source_client(const SourceConfig& source);

// Frames a client hands over while the loop's socket is full (PUSH's
// queue, ZMQ_SNDHWM) are dropped at the source and counted.
constexpr int kSourceQueueMessages = 1000;

class SourceFrames;

// Names a reload gives the loop's thread hands to a source's client thread, which takes them
// before its next frame: one atomic load a frame, the lock only to swap.
class PendingNames {
 public:
  // The loop's thread. Does not allocate: the names replaced leave with the argument.
  void put(std::vector<std::string> names);
  // The client's thread: the names, pending or not (at its start).
  std::vector<std::string> take();
  // The client's thread: maps `frames` to the pending names, if any. All or nothing: should
  // an allocation throw, the names wait for the next frame (unless newer ones came).
  void apply_to(SourceFrames& frames);

 private:
  std::mutex mutex_;
  std::vector<std::string> names_;
  std::atomic<bool> pending_{false};
};

class SourceInput {
 public:
  // Binds a PULL socket at a fresh inproc address (the loop polls socket())
  // and starts the client's thread.
  // `taken`: the names the daemon takes as they are (SourceFrames).
  SourceInput(zmq::context_t& context, const SourceConfig& source, const LabAxes& lab,
              std::vector<std::string> taken, SourceClient client);
  // Asks the client to stop and joins its thread.
  ~SourceInput();
  SourceInput(const SourceInput&) = delete;
  SourceInput& operator=(const SourceInput&) = delete;

  zmq::socket_t& socket() { return pull_; }
  const SourceConfig& config() const { return config_; }
  // A reload may have changed the names the daemon takes: the client's thread maps the
  // server's names again before its next frame, the connection kept. Frames already queued
  // for the loop are read with the new names. The loop's thread only; does not allocate.
  void retake(std::vector<std::string> taken);

  struct Status {
    bridges::SourceStatus::Snapshot connection;
    std::uint64_t frames_dropped = 0;  // handed over while the loop's queue was full
  };
  Status status() const;
  // Logs what changed since the last call (connected, lost, a new error);
  // errors at most once a second. Called from the loop.
  void log_changes();

 private:
  void run(std::stop_token stop, zmq::context_t& context, SourceClient client);

  SourceConfig config_;
  LabAxes lab_;
  PendingNames taken_;  // for the client's thread
  std::string endpoint_;
  zmq::socket_t pull_;
  bridges::SourceStatus status_;
  std::atomic<std::uint64_t> frames_dropped_{0};
  bridges::SourceStatus::Snapshot logged_;
  RateLimitedLog error_log_;
  std::jthread thread_;  // last: stopped and joined first
};

}  // namespace fabrik::wire
