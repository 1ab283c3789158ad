// `fabrik bench latency`: the daemon pipeline (decode, solve, encode,
// publish) on its own thread, fed by a marker source at a fixed rate over
// loopback tcp and ipc; end-to-end latency from the source's send to the
// subscriber's receive, on one steady clock, against the floor: a bare
// ZeroMQ echo of the same sizes (zmq_floor.hpp), fed in alternating blocks
// in the same run. With sources: the same for a
// frame from a simulated QTM or NatNet server, which fabrikd's own client
// decodes, against frames on the ZeroMQ input of the same daemon.
#pragma once

#include <chrono>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fabrik::bench {

struct LatencyOptions {
  double rate_hz = 1000.0;
  double seconds = 10.0;  // per transport, for the daemon and for the floor each
  // The daemon and the floor take turns in blocks this long.
  double block_seconds = 0.25;
  // A daemon config file (as `fabrik calibrate` writes it); empty: the
  // built-in default. Its model's synthetic motion makes the marker frames.
  std::string config;
  std::vector<std::string> transports = {"tcp", "ipc"};
  std::string encoding = "json";  // of the marker frames and poses
  // "none"; "mixed": markers plus an orientation sensor on every segment;
  // "only": the sensors alone (the frames' `orientations`, wire contract addition).
  std::string orientations = "none";
  // Vendor sources ("qtm", "natnet") to compare with the ZeroMQ input, each
  // in a run of its own: one daemon fed by both inputs, alternately. Empty:
  // only the transports above.
  std::vector<std::string> sources;
  // The daemon's total input rate in a source run, split evenly between the
  // source and the ZeroMQ input (moderate: the comparison is of latency, not
  // of throughput).
  double source_rate_hz = 500.0;
  // Subscribe to a pose view (output.views, topic "bench") of these optional
  // pose parts ("none": the required fields only) instead of to `pose`, as a
  // client that wants only them: the full pose is then not made. Empty: `pose`.
  std::vector<std::string> view_parts;
};
nlohmann::json run_latency(const LatencyOptions& options);
std::string latency_table(const nlohmann::json& result);
// The daemon's own stages over a run, from the stats messages it published
// (`bodies`, in the output's `encoding`, json or msgpack): per stage the median
// over the intervals of each interval's stages_us p50, `decode_solve_encode`
// their sum but the send's (what the floor does not do), and `intervals`, how
// many counted. An interval that served no frame (solve p50 not above zero) or
// that lacks a stage is left out.
nlohmann::json daemon_stages(const std::vector<std::string>& bodies, const std::string& encoding);

// When a run stops waiting for answers: once sending is done, after `quiet` without a frame.
// Kept in time, not in polls that time out: the daemon's stats keep its socket busy while
// frames no longer come, and a lost frame must not hold the run open.
class QuietDeadline {
 public:
  using Clock = std::chrono::steady_clock;
  explicit QuietDeadline(Clock::duration quiet) : quiet_(quiet) {}
  void sending_done(Clock::time_point now) {
    if (give_up_ == Clock::time_point::max()) give_up_ = now + quiet_;
  }
  void frame(Clock::time_point now) {
    if (give_up_ != Clock::time_point::max()) give_up_ = now + quiet_;
  }
  bool expired(Clock::time_point now) const { return now >= give_up_; }

 private:
  Clock::duration quiet_;
  Clock::time_point give_up_ = Clock::time_point::max();
};

}  // namespace fabrik::bench
